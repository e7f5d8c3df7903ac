// bomc viewer: replay of a finished pass (issue 19, item 3), like a behaviour-tree log replay.
// The server hands over a session's whole timeline once (/api/timeline, bomc_bt/viewer/replay.py);
// any moment is rebuilt here: the pose and the frame are the last ones at or before it, the tree
// is the status changes applied up to it, the objects the pass's starting map plus its events.
// While a moment is shown (R.t is not null) the map draws that moment instead of the final map.
"use strict";
(() => {
  const V = window.bomcViewer;
  const $ = (id) => document.getElementById(id);
  const esc = V.esc, fmt = V.fmt;
  const STATUS = { s: "success", f: "failure", r: "running", i: "invalid" };
  const FRAME_SHOWN_S = 1.5;  // a frame's detections are shown this long after it (robot seconds)
  const RECENT_S = 10;  // changes this recent are highlighted on the map
  const R = { session: null, data: null, t: null, playing: false, timer: null, moment: null, error: "" };

  // ------------------------------------------------------------------ the panels
  const bar = document.createElement("div");
  bar.id = "replay";
  bar.className = "replay site-only";
  bar.innerHTML = '<button id="replay-play" title="play / pause" disabled>▶</button>' +
    '<input id="replay-t" type="range" min="0" max="1" step="any" value="0" disabled>' +
    '<span id="replay-time">no timeline</span>' +
    '<label>speed <select id="replay-speed">' + [1, 5, 10, 30, 100].map((v) => `<option value="${v}"${v === 10 ? " selected" : ""}>${v}×</option>`).join("") + "</select></label>" +
    '<button id="replay-exit" title="back to the map after the pass" disabled>final map</button>';
  $("centre").insertBefore(bar, $("legend"));
  const side = document.createElement("div");
  side.id = "replay-side";
  side.className = "site-only replay-side";
  side.innerHTML = '<h2>Replay: detections</h2><canvas id="replay-camera" width="240" height="150"></canvas>' +
    '<ol id="replay-detections" class="events"></ol><h2>Replay: tree</h2><div id="replay-tree" class="tree"></div>';
  $("sessions").after(side);

  // --------------------------------------------------------------- the timeline
  async function load(n) {
    stop();
    R.session = n; R.data = null; R.t = null; R.moment = null; R.error = "";
    bar.dataset.ready = "";
    if (!n) { show(); return; }
    const d = await (await fetch(`/api/timeline?session=${n}`)).json();
    if (R.session !== n) return;  // another session was chosen meanwhile
    if (d.error) { R.error = d.error; show(); return; }
    R.data = d;
    const slider = $("replay-t");
    slider.min = String(d.start); slider.max = String(d.end); slider.value = String(d.start);
    bar.dataset.ready = String(n);
    show();
  }
  const lastAt = (items, t) => {  // index of the last item with .t <= t (-1: none)
    let lo = 0, hi = items.length - 1, found = -1;
    while (lo <= hi) { const mid = (lo + hi) >> 1; if (items[mid].t <= t) { found = mid; lo = mid + 1; } else hi = mid - 1; }
    return found;
  };

  function momentAt(t) {
    const d = R.data;
    const m = { t, pose: null, truth: null, frame: null, objects: [], highlight: {}, movedFrom: {}, removed: [], path: [] };
    const ip = lastAt(d.poses, t);
    if (ip >= 0) { m.pose = d.poses[ip].p; m.truth = d.poses[ip].g || null; }
    for (let i = 0; i <= ip; i++) { const p = d.poses[i].p; if (p) m.path.push(p[0], p[1]); }
    const jf = lastAt(d.frames, t);
    if (jf >= 0 && t - d.frames[jf].t <= FRAME_SHOWN_S) m.frame = d.frames[jf];
    const nodes = new Map(d.start_objects.map((n) => [n.id, { ...n }]));
    const colour = (c) => d.colours[c] || "#888888";
    d.events.slice(0, lastAt(d.events, t) + 1).forEach((rec) => rec.e.forEach(([kind, id, cat, x, y, fx, fy]) => {
      const recent = t - rec.t <= RECENT_S;
      if (kind === "removed" || kind === "deleted") {
        if (recent && nodes.has(id)) m.removed.push(nodes.get(id));
        nodes.delete(id);
        return;
      }
      nodes.set(id, { ...(nodes.get(id) || {}), id, category: cat, x, y, colour: colour(cat) });
      if (recent && kind === "added") m.highlight[id] = "added";
      if (recent && kind === "moved" && fx !== null) { m.highlight[id] = "moved"; m.movedFrom[id] = [fx, fy]; }
    }));
    m.objects = Array.from(nodes.values());
    const status = new Array(d.tree.length).fill("i"), feedback = new Array(d.tree.length).fill("");
    d.status.slice(0, lastAt(d.status, t) + 1).forEach((rec) => rec.c.forEach(([i, st, fb]) => { status[i] = st; feedback[i] = fb; }));
    m.status = status; m.feedback = feedback;
    return m;
  }

  // ------------------------------------------------------------------- showing
  function seek(t) {
    if (!R.data) return;
    R.t = Math.min(Math.max(t, R.data.start), R.data.end);
    R.moment = momentAt(R.t);
    $("replay-t").value = String(R.t);
    show();
    V.draw();
  }
  function show() {
    const has = !!R.data, m = R.moment;
    ["replay-play", "replay-t", "replay-exit"].forEach((id) => { $(id).disabled = !has; });
    $("replay-play").textContent = R.playing ? "❚❚" : "▶";
    bar.dataset.t = R.t === null ? "" : String(R.t);
    $("replay-time").textContent = !has ? (R.error || "no timeline") :
      R.t === null ? `session ${R.session}: ${fmt(R.data.start)}–${fmt(R.data.end)} s, scrub to replay` :
        `t = ${fmt(R.t)} s of ${fmt(R.data.end)} s`;
    side.classList.toggle("active", !!m);
    renderTree(m); renderDetections(m);
  }
  function renderTree(m) {
    const box = $("replay-tree");
    if (!m || !R.data.tree.length) { box.innerHTML = '<div class="none">scrub the timeline to see the tree</div>'; return; }
    const rows = R.data.tree, kids = rows.map(() => []);
    rows.forEach((r, i) => { if (r[3] >= 0) kids[r[3]].push(i); });
    const html = (i) => {
      const [name, kind, type] = rows[i], st = STATUS[m.status[i]] || "invalid", fb = m.feedback[i];
      let out = `<li class="node st-${st}" data-name="${esc(name)}" data-status="${st}"><div class="row"><span class="toggle"></span>` +
        `<span class="dot"></span><span class="name">${esc(name)}</span><span class="kind">${esc(kind === "behaviour" ? type : kind)}</span>`;
      if (fb) out += `<span class="fb" title="${esc(fb)}">${esc(fb)}</span>`;
      out += "</div>";
      if (kids[i].length) out += "<ul>" + kids[i].map(html).join("") + "</ul>";
      return out + "</li>";
    };
    box.innerHTML = "<ul>" + html(0) + "</ul>";
  }
  function renderDetections(m) {
    const list = $("replay-detections"), cam = $("replay-camera"), g = cam.getContext("2d");
    g.fillStyle = "#2a2f3a"; g.fillRect(0, 0, cam.width, cam.height);
    const f = m && m.frame;
    cam.dataset.frame = f ? String(f.n) : "";
    if (!f) { list.innerHTML = m ? '<li class="none">no frame at this moment</li>' : ""; return; }
    const [w, h] = f.wh || [640, 480], k = Math.min(cam.width / w, cam.height / h);
    const ox = (cam.width - w * k) / 2, oy = (cam.height - h * k) / 2;
    g.strokeStyle = "#8a8f99"; g.strokeRect(ox, oy, w * k, h * k);
    f.d.forEach(([cat, x0, y0, x1, y1, score]) => {
      g.strokeStyle = R.data.colours[cat] || "#fff"; g.lineWidth = 2;
      g.strokeRect(ox + x0 * k, oy + y0 * k, (x1 - x0) * k, (y1 - y0) * k);
      g.fillStyle = g.strokeStyle; g.font = "10px sans-serif"; g.fillText(`${cat} ${fmt(score, 2)}`, ox + x0 * k + 2, oy + y0 * k + 10);
    });
    list.innerHTML = `<li class="frame" data-frame="${f.n}">frame ${f.n} at ${fmt(f.t)} s: ${f.d.length} detections</li>` +
      f.d.map(([cat, x0, y0, x1, y1, score]) => `<li class="det" data-category="${esc(cat)}" data-score="${score}">` +
        `<span class="sw" style="background:${R.data.colours[cat] || "#888"}"></span>${esc(cat)} ${fmt(score, 2)} ` +
        `<span class="t">[${[x0, y0, x1, y1].map((v) => Math.round(v)).join(", ")}]</span></li>`).join("");
  }

  // ------------------------------------------------------------ on the map
  V.extend.scene.push((scene) => {
    const m = R.moment;
    if (!m || R.t === null) return scene;
    return { ...scene, robot: m.pose, path: m.path, waypoints: [], objects: m.objects, highlight: m.highlight,
      movedFrom: m.movedFrom, removed: m.removed };
  });
  V.extend.overlay.push((g, v, scene, dpr) => {
    const m = R.moment;
    if (!m || R.t === null) return;
    if (m.truth) {  // the simulator's true pose, beside the estimate
      const [x, y] = V.toCanvas(v, m.truth[0], m.truth[1]);
      g.beginPath(); g.arc(x, y, Math.max(6 * dpr, 0.25 * v.k) + 2 * dpr, 0, 2 * Math.PI);
      g.strokeStyle = "#1d2330"; g.lineWidth = 1.5 * dpr; g.setLineDash([3 * dpr, 2 * dpr]); g.stroke(); g.setLineDash([]);
    }
    ((m.frame || {}).o || []).forEach(([cat, ox, oy]) => {  // where this frame's detections landed on the map
      const [x, y] = V.toCanvas(v, ox, oy), s = 7 * dpr;
      g.strokeStyle = R.data.colours[cat] || "#000"; g.lineWidth = 2.5 * dpr; g.strokeRect(x - s, y - s, 2 * s, 2 * s);
    });
  });
  V.extend.session.push((n) => { if (n !== R.session) load(n); });
  // The site's data may have come before this script did (it loads after app.js): catch up.
  if (V.state.site.session !== null) load(V.state.site.session);

  // ------------------------------------------------------------------ controls
  function stop() { R.playing = false; if (R.timer) clearInterval(R.timer); R.timer = null; }
  function play() {
    if (!R.data) return;
    if (R.t === null || R.t >= R.data.end) seek(R.data.start);
    R.playing = true;
    let last = performance.now();
    R.timer = setInterval(() => {
      const now = performance.now(), speed = +$("replay-speed").value;
      seek(R.t + speed * (now - last) / 1000); last = now;
      if (R.t >= R.data.end) { stop(); show(); }
    }, 100);
    show();
  }
  $("replay-t").addEventListener("input", (e) => { stop(); seek(+e.target.value); });
  $("replay-play").addEventListener("click", () => { if (R.playing) { stop(); show(); } else play(); });
  $("replay-exit").addEventListener("click", () => { stop(); R.t = null; R.moment = null; show(); V.draw(); });
  show();
  window.bomcReplay = { state: R, seek, momentAt };
})();
