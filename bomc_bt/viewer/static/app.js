// bomc viewer: renders the sections pushed by bomc_bt/viewer/server.py (server-sent events).
// The page keeps the latest value of every section; a message carries only the sections that
// changed. EventSource reconnects by itself and sends the last event id, so after a dropped
// connection the server sends what was missed (or everything, after a server restart).
"use strict";

const S = {
  version: 0, sections: {}, connected: false, ended: false, draws: 0,
  map: { number: 0, img: null },
  collapsed: new Set(),
  site: { session: null, a: null, b: null, diff: null },
  view: null,  // world -> canvas transform of the last draw
};
// Modules that plug into the page (replay.js, corrections.js) register here: scene(scene) may
// return another scene to draw, overlay(g, view, scene, dpr) draws on the map, render(keys)
// follows new sections, session(n) follows the session chosen.
const EXT = { scene: [], overlay: [], render: [], session: [] };
const $ = (id) => document.getElementById(id);
const esc = (s) => String(s).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
const fmt = (v, d = 1) => (typeof v === "number" ? v.toFixed(d) : "–");
const COLOURS = { robot: "#e0203a", path: "#3c78c8", frontier: "#f08a24", waypoint: { pending: "#8a8f99", visited: "#2e9d4f", detoured: "#1f9e9a", missed: "#d23a3a" } };

// ------------------------------------------------------------------- connection
function connect() {
  const es = new EventSource("/events");
  es.onopen = () => setConnected(true);
  es.onerror = () => setConnected(false);
  // The server says goodbye when its mission (or `bomc view`) ends: the badge turns grey, not
  // "reconnecting" red; EventSource keeps trying, so a new mission on this port still shows.
  es.addEventListener("end", () => { S.ended = true; setConnected(false); });
  es.onmessage = (e) => {
    const msg = JSON.parse(e.data);
    setConnected(true);
    if (msg.full) S.sections = {};
    Object.assign(S.sections, msg.sections);
    S.version = msg.version;
    document.body.dataset.version = String(msg.version);
    render(msg.full ? Object.keys(S.sections) : Object.keys(msg.sections));
  };
}
function setConnected(on) {
  S.connected = on;
  if (on) S.ended = false;
  const site = S.sections.mode === "site";
  const el = $("conn");
  el.className = "conn " + (on ? "on" : S.ended ? "ended" : "off");
  el.textContent = on ? (site ? "connected" : "live") : S.ended ? (site ? "viewer stopped" : "mission ended")
    : "reconnecting…";
  document.body.dataset.connected = on ? "yes" : S.ended ? "ended" : "no";
}

function render(keys) {
  const has = (k) => keys.includes(k);
  if (has("mode")) { document.body.className = "mode-" + (S.sections.mode || "none"); setConnected(true); }
  if (has("tree")) renderTree(S.sections.tree);
  if (has("blackboard")) renderBlackboard(S.sections.blackboard || []);
  if (has("progress")) renderProgress(S.sections.progress);
  if (has("events")) renderEvents((S.sections.events || {}).items || []);
  if (has("site")) initSite(S.sections.site);
  if (has("map")) loadMap(S.sections.map);
  EXT.render.forEach((f) => f(keys));
  draw();
}

// ------------------------------------------------------------------------- tree
function renderTree(root) {
  const box = $("tree");
  if (!root) { box.innerHTML = ""; return; }
  const running = [];
  const html = (node, path) => {
    const kids = node.children || [];
    const status = node.status || "invalid";
    if (status === "running") running.push(node.name);
    const collapsed = S.collapsed.has(path);
    const toggle = kids.length ? (collapsed ? "▸" : "▾") : "";
    let out = `<li class="node st-${esc(status)}${collapsed ? " collapsed" : ""}" data-path="${path}" data-name="${esc(node.name)}" data-status="${esc(status)}">`;
    out += `<div class="row"><span class="toggle">${toggle}</span><span class="dot"></span><span class="name">${esc(node.name)}</span>`;
    out += `<span class="kind">${esc(node.kind === "behaviour" ? node.type : node.kind)}</span>`;
    if (node.feedback) out += `<span class="fb" title="${esc(node.feedback)}">${esc(node.feedback)}</span>`;
    out += "</div>";
    if (kids.length) out += "<ul>" + kids.map((c, i) => html(c, path + "." + i)).join("") + "</ul>";
    return out + "</li>";
  };
  box.innerHTML = "<ul>" + html(root, "0") + "</ul>";
  $("running-path").textContent = running.length ? "▶ " + running.join(" › ") : "";
}
function onTreeClick(e) {
  const t = e.target.closest(".toggle");
  if (!t || !t.textContent) return;
  const li = t.closest(".node");
  const path = li.dataset.path;
  if (S.collapsed.has(path)) S.collapsed.delete(path); else S.collapsed.add(path);
  li.classList.toggle("collapsed");
  t.textContent = li.classList.contains("collapsed") ? "▸" : "▾";
}

function renderBlackboard(rows) {
  $("blackboard").innerHTML = rows.map(([k, v, who]) => `<tr data-key="${esc(k)}" title="${esc(who || "")}"><td>${esc(k)}</td><td>${esc(v)}</td><td class="ports">${esc(who || "")}</td></tr>`).join("")
    || '<tr><td colspan="3">(empty)</td></tr>';
}

function renderProgress(p) {
  if (!p) return;
  const items = [["t", fmt(p.sim_time) + " s"], ["status", p.status]];
  if (p.mission === "build") {
    items.push(["explored", fmt(p.explored_area) + " m²"], ["path", fmt(p.path_length) + " m"]);
    if (p.goals !== undefined) items.push(["goals", p.goals]);
  } else {
    items.push(["session", p.session], ["waypoint", `${p.waypoint} of ${p.waypoints}`], ["frames", p.frames],
      ["objects", p.nodes], ["path", fmt(p.path_length) + " m"]);
  }
  if (p.message) items.push(["", p.message]);
  $("progress").innerHTML = items.map(([k, v]) => `<span data-key="${esc(k)}"><b>${esc(k)}</b>${esc(v)}</span>`).join("");
  $("title").textContent = p.mission ? `${p.mission} mission` : "";
}

function eventLine(e) {
  const from = e.from ? ` from (${fmt(e.from[0], 2)}, ${fmt(e.from[1], 2)})` : "";
  return `<li class="ev k-${esc(e.kind)}" data-id="${e.id}"><span class="t">${fmt(e.stamp)} s</span><span class="tag">${esc(e.kind)}</span>` +
    `${esc(e.category)} #${e.id} at (${fmt(e.x, 2)}, ${fmt(e.y, 2)})${from}</li>`;
}
function renderEvents(items) {
  $("events").innerHTML = items.slice().reverse().map(eventLine).join("") || '<li class="none">no changes yet</li>';
}

// ------------------------------------------------------------------------- site
function initSite(site) {
  if (!site) return;
  $("title").textContent = `site ${site.name}`;
  const numbers = site.sessions.map((s) => s.number);
  const q = new URLSearchParams(location.search);
  const pick = (key, fallback) => { const v = parseInt(q.get(key), 10); return (v === 0 || numbers.includes(v)) ? v : fallback; };
  const def = site.default_diff || [0, 0];
  S.site.b = pick("b", def[1]);
  S.site.a = pick("a", def[0]);
  S.site.session = pick("session", S.site.b || numbers[numbers.length - 1] || 0);
  $("sessions").innerHTML = site.sessions.map((s) => {
    const c = s.counts || {};
    const counts = ["added", "removed", "moved"].map((k) => `${k} ${c[k] || 0}`).join(" · ");
    return `<li class="session" data-session="${s.number}"><b>Session ${s.number}</b> ${esc(s.outcome || (s.ended ? "" : "unfinished"))}` +
      `<div class="meta">${s.objects.length} objects · ${counts}</div></li>`;
  }).join("") || "<li>no monitor sessions yet</li>";
  const options = ['<option value="0">before session 1</option>'].concat(numbers.map((n) => `<option value="${n}">session ${n}</option>`)).join("");
  $("diff-a").innerHTML = options; $("diff-b").innerHTML = options;
  $("build").innerHTML = Object.entries(site.build || {}).filter(([, v]) => typeof v !== "object")
    .map(([k, v]) => `<tr><td>${esc(k)}</td><td>${esc(typeof v === "number" ? +v.toFixed(2) : v)}</td></tr>`).join("");
  selectSession(S.site.session, [S.site.a, S.site.b]);
  if (window.bomcHeatmap) bomcHeatmap.load(draw);  // heatmap.js: the change model over the map
}
function sessionData(n) { return ((S.sections.site || {}).sessions || []).find((s) => s.number === n); }
function selectSession(n, pair) {
  S.site.session = n;
  if (pair) { S.site.a = pair[0]; S.site.b = pair[1]; }
  $("diff-a").value = String(S.site.a); $("diff-b").value = String(S.site.b);
  document.querySelectorAll("#sessions li.session").forEach((li) => li.classList.toggle("selected", +li.dataset.session === n));
  const s = sessionData(n);
  $("events-title").textContent = n ? `Events of session ${n}` : "Events";
  renderEvents(s ? s.events : []);
  loadDiff();
  EXT.session.forEach((f) => f(n));
  draw();
}
async function loadDiff() {
  const { a, b } = S.site;
  const box = $("diff");
  box.dataset.pair = `${a}-${b}`;
  const r = await fetch(`/api/diff?a=${a}&b=${b}`);
  const d = await r.json();
  if (S.site.a !== a || S.site.b !== b) return;  // a newer choice is on its way
  if (d.error) { box.innerHTML = `<div class="none">${esc(d.error)}</div>`; return; }
  S.site.diff = d;
  const part = (kind) => {
    const items = d[kind];
    const li = items.map((n) => `<li class="k-${kind}" data-id="${n.id}"><span class="tag">${kind}</span>${esc(n.category)} #${n.id}` +
      (n.from ? ` ${fmt(n.distance, 2)} m` : "") + "</li>").join("");
    return `<h3>${kind} (${items.length})</h3><ul id="diff-${kind}">${li || '<li class="none">none</li>'}</ul>`;
  };
  box.innerHTML = `<div id="diff-summary">session ${a} → session ${b}</div>` + ["added", "removed", "moved", "first_seen", "retracted"].map(part).join("");
  box.dataset.ready = `${a}-${b}`;
  draw();
}
function onSessionsClick(e) {
  const li = e.target.closest("li.session");
  if (!li) return;
  const n = +li.dataset.session;
  const numbers = S.sections.site.sessions.map((s) => s.number);
  const i = numbers.indexOf(n);
  selectSession(n, [i > 0 ? numbers[i - 1] : 0, n]);
}
function onCompareChange() {
  const a = +$("diff-a").value, b = +$("diff-b").value;
  selectSession(b || S.site.session, [a, b]);
}

// -------------------------------------------------------------------------- map
function loadMap(meta) {
  if (!meta || meta.number === S.map.number) return;
  const img = new Image();
  img.onload = () => { if (meta.number >= S.map.number) { S.map = { number: meta.number, img, meta }; draw(); } };
  img.src = `/map.png?v=${meta.number}`;
}

// What the map shows: the live scene, or a site session with the chosen difference.
function currentScene() {
  const sec = S.sections;
  if (sec.mode !== "site") {
    const scene = sec.scene || {};
    const removed = ((sec.events || {}).items || []).filter((e) => e.kind === "removed");
    const moved = {};
    ((sec.events || {}).items || []).forEach((e) => { if (e.kind === "moved" && e.from) moved[e.id] = e.from; });
    return { ...scene, removed, movedFrom: moved, highlight: scene.highlight || {} };
  }
  const site = sec.site || {};
  const s = sessionData(S.site.session);
  const scene = { path: site.path || [], waypoints: site.waypoints || [], objects: s ? s.objects : [], robot: null,
    frontiers: [], blacklist: [], removed: [], movedFrom: {}, highlight: {} };
  const d = S.site.diff;
  if (d && d.b === S.site.session) {
    d.added.forEach((n) => { scene.highlight[n.id] = "added"; });
    d.moved.forEach((n) => { scene.highlight[n.id] = "moved"; scene.movedFrom[n.id] = n.from; });
    scene.removed = d.removed;
  }
  return EXT.scene.reduce((sc, f) => f(sc) || sc, scene);
}

function fitView(canvas, scene) {
  const m = S.map.meta;
  let x0, y0, x1, y1;
  if (m) {
    x0 = m.origin[0]; y0 = m.origin[1];
    x1 = x0 + m.width * m.resolution; y1 = y0 + m.height * m.resolution;
  } else {  // no map yet: fit whatever is there
    const xs = [], ys = [];
    const add = (x, y) => { xs.push(x); ys.push(y); };
    if (scene.robot) add(scene.robot[0], scene.robot[1]);
    (scene.objects || []).forEach((n) => add(n.x, n.y));
    for (let i = 0; i + 1 < (scene.path || []).length; i += 2) add(scene.path[i], scene.path[i + 1]);
    if (!xs.length) { add(-5, -5); add(5, 5); }
    x0 = Math.min(...xs) - 2; x1 = Math.max(...xs) + 2; y0 = Math.min(...ys) - 2; y1 = Math.max(...ys) + 2;
  }
  const pad = 10;
  const k = Math.min((canvas.width - 2 * pad) / (x1 - x0), (canvas.height - 2 * pad) / (y1 - y0));
  const ox = (canvas.width - k * (x1 - x0)) / 2, oy = (canvas.height - k * (y1 - y0)) / 2;
  return { k, x0, y1, ox, oy, w: (x1 - x0) * k, h: (y1 - y0) * k };
}
const toCanvas = (v, x, y) => [v.ox + (x - v.x0) * v.k, v.oy + (v.y1 - y) * v.k];

function draw(again = true) {
  const canvas = $("map");
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const g = canvas.getContext("2d");
  const scene = currentScene();
  const v = fitView(canvas, scene);
  S.view = v;
  g.setTransform(1, 0, 0, 1, 0, 0);
  g.fillStyle = "#cdcdcd";
  g.fillRect(0, 0, w, h);
  if (S.map.img) {  // crisp cells when enlarged; averaged when shrunk, or thin walls would vanish
    g.imageSmoothingEnabled = v.w < S.map.img.width;
    g.drawImage(S.map.img, v.ox, v.oy, v.w, v.h);
  }
  if (S.sections.mode === "site" && window.bomcHeatmap) bomcHeatmap.draw(g, v, toCanvas, S.site.session);  // heatmap.js
  const px = (m) => Math.max(1, m * v.k);
  // frontiers and blacklisted goals
  g.fillStyle = COLOURS.frontier;
  (scene.frontiers || []).forEach((f) => {
    const c = f.cells || [], s = Math.max(1.5, px(0.05));
    for (let i = 0; i + 1 < c.length; i += 2) { const [x, y] = toCanvas(v, c[i], c[i + 1]); g.fillRect(x - s / 2, y - s / 2, s, s); }
    const [x, y] = toCanvas(v, f.centroid[0], f.centroid[1]);
    g.beginPath(); g.arc(x, y, 4 * dpr, 0, 2 * Math.PI); g.strokeStyle = COLOURS.frontier; g.lineWidth = 2 * dpr; g.stroke();
  });
  (scene.blacklist || []).forEach(([bx, by]) => cross(g, toCanvas(v, bx, by), 4 * dpr, "#7a1010", 1.5 * dpr));
  // path
  const p = scene.path || [];
  if (p.length >= 4) {
    g.beginPath();
    for (let i = 0; i + 1 < p.length; i += 2) { const [x, y] = toCanvas(v, p[i], p[i + 1]); i ? g.lineTo(x, y) : g.moveTo(x, y); }
    g.strokeStyle = COLOURS.path; g.lineWidth = 1.5 * dpr; g.stroke();
  }
  // waypoints
  (scene.waypoints || []).forEach((wp) => {
    const [x, y] = toCanvas(v, wp.x, wp.y);
    const c = COLOURS.waypoint[wp.state] || COLOURS.waypoint.pending;
    g.beginPath(); g.arc(x, y, 4 * dpr, 0, 2 * Math.PI);
    if (wp.state === "pending") { g.strokeStyle = c; g.lineWidth = 1.5 * dpr; g.stroke(); } else { g.fillStyle = c; g.fill(); }
    if (wp.current) { g.beginPath(); g.arc(x, y, 8 * dpr, 0, 2 * Math.PI); g.strokeStyle = COLOURS.path; g.lineWidth = 2 * dpr; g.stroke(); }
  });
  // objects, changes highlighted
  const r = Math.max(4 * dpr, px(0.2));
  (scene.removed || []).forEach((n) => cross(g, toCanvas(v, n.x, n.y), r * 1.2, "#d23a3a", 2.5 * dpr));
  const cats = {};
  (scene.objects || []).forEach((n) => {
    cats[n.category] = n.colour;
    const [x, y] = toCanvas(v, n.x, n.y);
    const mark = scene.highlight[n.id];
    if (mark === "moved" && scene.movedFrom[n.id]) {
      const [fx, fy] = toCanvas(v, scene.movedFrom[n.id][0], scene.movedFrom[n.id][1]);
      g.setLineDash([4 * dpr, 3 * dpr]); g.beginPath(); g.moveTo(fx, fy); g.lineTo(x, y);
      g.strokeStyle = "#c23bd6"; g.lineWidth = 1.5 * dpr; g.stroke(); g.setLineDash([]);
    }
    if (mark === "added" || mark === "moved") {
      g.beginPath(); g.arc(x, y, r + 4 * dpr, 0, 2 * Math.PI);
      g.fillStyle = mark === "added" ? "rgba(242,194,0,.55)" : "rgba(194,59,214,.45)"; g.fill();
    }
    g.beginPath(); g.arc(x, y, r, 0, 2 * Math.PI); g.fillStyle = n.colour; g.fill();
    g.strokeStyle = "#1e1e1e"; g.lineWidth = 1 * dpr; g.stroke();
    g.fillStyle = "#141414"; g.font = `${10 * dpr}px sans-serif`; g.fillText(String(n.id), x + r + 1, y - r + 2);
  });
  // the robot on top
  if (scene.robot) {
    const [x, y] = toCanvas(v, scene.robot[0], scene.robot[1]);
    const rr = Math.max(6 * dpr, px(0.25)), yaw = scene.robot[2];
    g.beginPath(); g.arc(x, y, rr, 0, 2 * Math.PI); g.fillStyle = COLOURS.robot; g.fill();
    const c = Math.cos(yaw), s = Math.sin(yaw);  // the heading, outside the body: its centre stays red
    g.beginPath(); g.moveTo(x + c * rr * 0.4, y - s * rr * 0.4); g.lineTo(x + c * rr * 1.7, y - s * rr * 1.7);
    g.strokeStyle = "#1d2330"; g.lineWidth = 2 * dpr; g.stroke();
  }
  EXT.overlay.forEach((f) => f(g, v, scene, dpr));
  $("legend").innerHTML = Object.keys(cats).sort().map((c) => `<span data-category="${esc(c)}"><span class="sw" style="background:${cats[c]}"></span>${esc(c)}</span>`).join("");
  S.draws += 1;
  canvas.dataset.draws = String(S.draws);
  // A new legend row can change the page's layout and so the canvas's size: draw again at
  // the size it has now (reading it lays the page out), or the map stays stretched.
  const nw = Math.max(1, Math.round(canvas.clientWidth * dpr)), nh = Math.max(1, Math.round(canvas.clientHeight * dpr));
  if (again !== false && (nw !== w || nh !== h)) draw(false);
}
function cross(g, [x, y], s, colour, width) {
  g.beginPath(); g.moveTo(x - s, y - s); g.lineTo(x + s, y + s); g.moveTo(x + s, y - s); g.lineTo(x - s, y + s);
  g.strokeStyle = colour; g.lineWidth = width; g.stroke();
}

// For people poking at the page and for the browser tests: read the canvas at a world point.
window.bomcViewer = {
  state: S, extend: EXT, draw, toCanvas, esc, fmt, sessionData, COLOURS,
  pixelAtWorld(x, y) {
    if (!S.view) return null;
    const [cx, cy] = toCanvas(S.view, x, y);
    return Array.from($("map").getContext("2d").getImageData(Math.round(cx), Math.round(cy), 1, 1).data);
  },
};

$("tree").addEventListener("click", onTreeClick);
$("sessions").addEventListener("click", onSessionsClick);
$("diff-a").addEventListener("change", onCompareChange);
$("diff-b").addEventListener("change", onCompareChange);
window.addEventListener("resize", () => draw());
new ResizeObserver(() => draw()).observe($("map"));  // panels that grow or shrink resize the map too
setConnected(false);
connect();
