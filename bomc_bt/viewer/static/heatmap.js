// The change model's heat map over the site map (issue 20; data: /api/change_model, bomc_bt/viewer/heatmap.py).
// Each region of the map is filled in red, the stronger the more changes are expected to be
// waiting there at the next pass (rate per pass x passes since a pass last saw it). The
// regions the selected session skipped (a pass with a budget) are outlined, dashed. app.js
// calls bomcHeatmap.load(redraw) once a site is shown and bomcHeatmap.draw(...) right after
// drawing the map image, so objects and paths stay on top. A checkbox over the map's corner turns it on (off at first: the plain map).
"use strict";

const bomcHeatmap = (() => {
  // settled: the model's request has ended (drawn or not): a page read before that may be redrawn under it
  const H = { data: null, on: false, requested: false, settled: false, max: 0 };  // off until asked
  const FILL = [214, 40, 30];  // red; alpha grows with the changes waiting
  const MIN_ALPHA = 0.08, MAX_ALPHA = 0.6;

  function load(redraw) {
    if (H.requested) return;
    H.requested = true;
    fetch("/api/change_model")
      .then((r) => (r.ok ? r.json() : null))
      .then((data) => {
        if (!data || !Array.isArray(data.regions)) return;
        H.data = data;
        H.max = data.max_waiting || 0;
        addToggle(redraw);
        redraw();
      })
      .catch(() => {})  // an old server without the route: no heat map
      .finally(() => { H.settled = true; });
  }

  function addToggle(redraw) {
    if (document.getElementById("heatmap-toggle")) return;
    // over the map's top-right corner, not below it: the canvas keeps its size whether or not
    // the site has a change model (a floor read from the central store has none)
    const wrap = document.getElementById("map").parentNode;
    const label = document.createElement("label");
    label.className = "heatmap-toggle";
    label.style.cssText = "position:absolute; top:6px; right:8px; z-index:2; font-size:12px; " +
      "background:rgba(255,255,255,.85); padding:2px 6px; border-radius:4px;";
    label.innerHTML = `<input type="checkbox" id="heatmap-toggle"> heat map: changes expected waiting ` +
      `(most ${H.max.toFixed(2)} in a ${H.data.size_m} m square; dashed: skipped by the session)`;
    wrap.appendChild(label);
    label.querySelector("input").addEventListener("change", (e) => { H.on = e.target.checked; redraw(); });
  }

  function alpha(waiting) {
    return H.max > 0 ? MIN_ALPHA + (MAX_ALPHA - MIN_ALPHA) * Math.min(1, waiting / H.max) : 0;
  }

  // g: the canvas context, v: the world -> canvas view, toCanvas(v, x, y), session: the one shown.
  function draw(g, v, toCanvas, session) {
    if (!H.on || !H.data) return;
    const half = H.data.size_m / 2;
    const square = (r) => {
      const [x0, y0] = toCanvas(v, r.x - half, r.y + half);
      const [x1, y1] = toCanvas(v, r.x + half, r.y - half);
      return [x0, y0, x1 - x0, y1 - y0];
    };
    H.data.regions.forEach((r) => {
      const a = alpha(r.waiting);
      if (a <= 0) return;
      g.fillStyle = `rgba(${FILL[0]},${FILL[1]},${FILL[2]},${a.toFixed(3)})`;
      g.fillRect(...square(r));
    });
    const skipped = (H.data.skipped || {})[String(session)] || [];
    if (skipped.length) {
      g.save();
      g.setLineDash([6, 4]);
      g.strokeStyle = "#6a1b9a";
      g.lineWidth = 2;
      skipped.forEach((r) => g.strokeRect(...square(r)));
      g.restore();
    }
  }

  return { load, draw, state: H };
})();
window.bomcHeatmap = bomcHeatmap;
