// bomc viewer: the operator's corrections from the site page (issue 19, item 4).
// Pick a node (from the list, or click it on the map), an action, a value; the server applies it
// with the code `bomc edit` runs (POST /api/edit, bomc_bt/viewer/corrections.py) and pushes the
// "corrections" section again: the map as it stands now and the operator's history.
"use strict";
(() => {
  const V = window.bomcViewer;
  const $ = (id) => document.getElementById(id);
  const esc = V.esc;
  const NEEDS_VALUE = { relabel: "new category", note: "note text" };
  const C = { busy: false, last: null };

  const panel = document.createElement("div");
  panel.id = "corrections";
  panel.className = "site-only";
  panel.innerHTML = "<h2>Corrections</h2>" +
    '<div class="edit-form"><select id="edit-node"></select>' +
    '<select id="edit-action">' + ["relabel", "delete", "restore", "note"].map((a) => `<option>${a}</option>`).join("") + "</select>" +
    '<input id="edit-value" maxlength="500" placeholder="new category"><button id="edit-apply">apply</button></div>' +
    '<div id="edit-result" class="edit-result"></div><ol id="edit-history" class="events"></ol>';
  $("right").insertBefore(panel, $("right").firstChild);

  const section = () => V.state.sections.corrections || {};
  const lastSession = () => Math.max(0, ...(((V.state.sections.site || {}).sessions) || []).map((s) => s.number));
  const replaying = () => !!(window.bomcReplay && window.bomcReplay.state.t !== null);

  function render() {
    const c = section();
    panel.dataset.available = c.available ? "yes" : "no";
    ["edit-node", "edit-action", "edit-value", "edit-apply"].forEach((id) => { $(id).disabled = !c.available || C.busy; });
    if (!c.available) { $("edit-result").textContent = c.why || ""; return; }
    const chosen = $("edit-node").value;
    $("edit-node").innerHTML = c.objects.map((n) => `<option value="${n.id}">#${n.id} ${esc(n.category)}` +
      `${n.state === "present" ? "" : " (" + esc(n.state) + ")"}</option>`).join("");
    if (chosen) $("edit-node").value = chosen;
    $("edit-history").innerHTML = c.edits.slice().reverse().map((e) => {
      const d = e.detail || {};
      const what = e.kind === "relabelled" ? `${esc(d.from)} → ${esc(e.category)}` : e.kind === "noted" ? `“${esc(d.text)}”` : esc(e.category);
      return `<li class="ev k-${esc(e.kind)}" data-id="${e.id}" data-kind="${esc(e.kind)}"><span class="tag">${esc(e.kind)}</span>#${e.id} ${what}` +
        `<span class="t"> for session ${e.session}</span></li>`;
    }).join("") || '<li class="none">no corrections yet</li>';
  }
  function onAction() {
    const a = $("edit-action").value;
    $("edit-value").disabled = !NEEDS_VALUE[a] || !section().available;
    $("edit-value").placeholder = NEEDS_VALUE[a] || "";
  }
  async function apply() {
    const action = $("edit-action").value, id = $("edit-node").value;
    const value = NEEDS_VALUE[action] ? $("edit-value").value.trim() : null;
    const box = $("edit-result");
    C.busy = true; render();
    try {
      const r = await fetch("/api/edit", { method: "POST", headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ action, id: +id, value }) });
      const d = await r.json();
      C.last = d;
      box.className = "edit-result " + (d.error ? "err" : "ok");
      box.textContent = d.error || d.message;
      box.dataset.state = d.error ? "error" : "done";
    } catch (e) {
      box.className = "edit-result err"; box.textContent = `the viewer did not answer (${e})`; box.dataset.state = "error";
    } finally {
      C.busy = false; render(); onAction();
    }
  }

  // The site's last session shows the map as it stands now: the operator's edits included.
  V.extend.scene.push((scene) => {
    const c = section();
    if (!c.available || replaying() || V.state.sections.mode !== "site" || V.state.site.session !== lastSession()) return scene;
    return { ...scene, objects: c.objects.filter((n) => n.state === "present") };
  });
  V.extend.overlay.push((g, v, scene, dpr) => {  // nodes the operator deleted: a grey cross
    const c = section();
    if (!c.available || replaying() || V.state.site.session !== lastSession()) return;
    const latest = {};
    c.edits.forEach((e) => { if (e.kind !== "noted") latest[e.id] = e; });
    Object.values(latest).filter((e) => e.kind === "deleted").forEach((e) => {
      const [x, y] = V.toCanvas(v, e.x, e.y), s = 6 * dpr;
      g.beginPath(); g.moveTo(x - s, y - s); g.lineTo(x + s, y + s); g.moveTo(x + s, y - s); g.lineTo(x - s, y + s);
      g.strokeStyle = "#6b7280"; g.lineWidth = 2 * dpr; g.stroke();
    });
  });
  V.extend.render.push((keys) => { if (keys.includes("corrections")) { render(); onAction(); } });
  if (V.state.sections.corrections) { render(); onAction(); }  // it came before this script

  // A click on the map picks the nearest object within 15 px for the form.
  $("map").addEventListener("click", (e) => {
    const view = V.state.view, c = section();
    if (!view || !c.available) return;
    const rect = $("map").getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
    const cx = (e.clientX - rect.left) * dpr, cy = (e.clientY - rect.top) * dpr;
    let best = null, bestD = 15 * dpr;
    c.objects.forEach((n) => {
      const [x, y] = V.toCanvas(view, n.x, n.y), d = Math.hypot(x - cx, y - cy);
      if (d < bestD) { best = n; bestD = d; }
    });
    if (best) $("edit-node").value = String(best.id);
  });
  $("edit-action").addEventListener("change", onAction);
  $("edit-apply").addEventListener("click", apply);
  render(); onAction();
  window.bomcCorrections = { state: C, apply };
})();
