// The Acquire view's zone map (the plan's candidates and chosen poses over theta_2 /
// theta_3, deg, model convention; each pose coloured by its rows in tests.csv, the pose
// being measured ringed) and the live readings of the test being measured. All read from
// the server's files: /api/acquire/map, /poses, /trace. Called by acquire.js on each
// state it shows (acqMap.update(state)).
(function () {
  "use strict";
  const el = (id) => document.getElementById(id);
  const dash = "\u2013";
  const STATUS = [  // series of the chosen poses: status, label, colour, size
    ["pending", "planned, not measured", "#ffffff", 10],
    ["partial", "some tests measured", "#f2c14e", 11],
    ["done", "done (every test ok)", "#1b9e77", 11],
    ["failed", "measured, a test failed", "#b00020", 11],
  ];
  const m = { key: null, map: null, plot: null, status: {}, rows: -1, current: null,
              trace: null, loading: null, xs: [], order: [], points: [] };

  async function get(url) {
    const r = await fetch(url, { credentials: "same-origin" });
    const d = await r.json();
    if (!r.ok) throw Object.assign(new Error(d.detail || r.statusText), { status: r.status });
    return d;
  }

  function fmt(v, digits) { return v === null || v === undefined ? dash : Number(v).toFixed(digits); }
  function vec(v, digits) { return v ? v.map((x) => fmt(x, digits)).join(", ") : dash; }

  // ---- the zone map ----
  function build(map) {
    const [a, b] = map.axes.map((j) => j - 1);
    const cand = map.candidates.q_deg;
    const points = [];
    for (let i = 0; i < map.candidates.count; i++) points.push({ kind: "candidate", i, x: cand[a][i], y: cand[b][i] });
    map.chosen.forEach((c, i) => points.push({ kind: "chosen", i, x: c.q_deg[a], y: c.q_deg[b] }));
    const order = points.map((_, i) => i).sort((p, q) => points[p].x - points[q].x);
    m.points = order.map((i) => points[i]);
    m.xs = m.points.map((p) => p.x);
    if (m.plot) { m.plot.destroy(); m.plot = null; }
    const series = [{ label: `theta${map.axes[0]} (deg)` },
      { label: `candidates passing the thresholds (${map.candidates.count})`, paths: () => null, stroke: "#8fb3c8",
        points: { show: true, size: 3, stroke: "#8fb3c8", fill: "#8fb3c8", width: 0 } }];
    for (const [, label, colour, size] of STATUS) {
      series.push({ label, paths: () => null, stroke: "#24344d", fill: colour,
                    points: { show: true, size, stroke: "#24344d", fill: colour, width: 1.5 } });
    }
    series.push({ label: "being measured", paths: () => null, stroke: "#d95f02",
                  points: { show: true, size: 20, stroke: "#d95f02", fill: "rgba(217,95,2,0.15)", width: 3 } });
    const opts = {
      width: 560, height: 420, scales: { x: { time: false } }, series,
      legend: { live: false },
      cursor: { drag: { x: true, y: true, uni: 30 }, points: { show: false } },
      axes: [{ label: `theta${map.axes[0]} (deg, model convention)` },
             { label: `theta${map.axes[1]} (deg, model convention)`, size: 60 }],
      hooks: { drawClear: [drawGrid], draw: [drawZones], setCursor: [hover] },
    };
    m.plot = new uPlot(opts, data(), el("acq-map"));
    el("acq-map").dataset.candidates = String(map.candidates.count);
    el("acq-map").dataset.chosen = String(map.chosen.length);
  }

  function data() {
    const n = m.points.length;
    const cols = [m.xs, m.points.map((p) => (p.kind === "candidate" ? p.y : null))];
    const chosen = m.map.chosen;
    for (const [status] of STATUS) {
      cols.push(m.points.map((p) => (p.kind === "chosen" &&
        (m.status[chosen[p.i].pose] || "pending") === status ? p.y : null)));
    }
    cols.push(m.points.map((p) => (p.kind === "chosen" && chosen[p.i].pose === m.current ? p.y : null)));
    return n ? cols : cols.map(() => []);
  }

  // the background: 1/kappa_F of J_N over (theta2, theta3), grey from dark (0) to light
  // (its largest value on the grid), as plan_map.png shades it
  function drawGrid(u) {
    const g = m.map.grid;
    if (!g) return;
    const ctx = u.ctx, t2 = g.theta2_deg, t3 = g.theta3_deg;
    const top = Math.max(...g.inv_kappa.map((row) => Math.max(...row)));
    const edge = (t, i) => (i === 0 ? t[0] : i === t.length ? t[t.length - 1] : (t[i - 1] + t[i]) / 2);
    ctx.save();
    ctx.beginPath();
    ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
    ctx.clip();
    for (let i3 = 0; i3 < t3.length; i3++) {
      const y0 = u.valToPos(edge(t3, i3), "y", true), y1 = u.valToPos(edge(t3, i3 + 1), "y", true);
      for (let i2 = 0; i2 < t2.length; i2++) {
        const x0 = u.valToPos(edge(t2, i2), "x", true), x1 = u.valToPos(edge(t2, i2 + 1), "x", true);
        const level = Math.round(70 + 180 * g.inv_kappa[i3][i2] / top);
        ctx.fillStyle = `rgb(${level},${level},${level})`;
        ctx.fillRect(Math.min(x0, x1), Math.min(y0, y1), Math.abs(x1 - x0) + 1, Math.abs(y1 - y0) + 1);
      }
    }
    ctx.restore();
  }

  function kappaAt(u, left, top) {  // 1/kappa_F of the grid point nearest the cursor
    const g = m.map.grid;
    if (!g) return "";
    const a = u.posToVal(left, "x"), b = u.posToVal(top, "y");
    const near = (t, v) => t.reduce((best, x, i) => (Math.abs(x - v) < Math.abs(t[best] - v) ? i : best), 0);
    const i2 = near(g.theta2_deg, a), i3 = near(g.theta3_deg, b);
    return `theta2 ${a.toFixed(1)} deg, theta3 ${b.toFixed(1)} deg: 1/kappa_F ${g.inv_kappa[i3][i2].toFixed(3)}`;
  }

  function drawZones(u) {
    const [a, b] = m.map.axes.map((j) => j - 1);
    const ctx = u.ctx;
    ctx.save();
    ctx.strokeStyle = "#2f6db5";
    ctx.fillStyle = "#2f6db5";
    ctx.lineWidth = 1.5 * devicePixelRatio;
    ctx.font = `${11 * devicePixelRatio}px sans-serif`;
    ctx.beginPath();
    ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
    ctx.clip();
    for (const z of m.map.zones) {
      const x0 = u.valToPos(z.lo_deg[a], "x", true), x1 = u.valToPos(z.hi_deg[a], "x", true);
      const y0 = u.valToPos(z.lo_deg[b], "y", true), y1 = u.valToPos(z.hi_deg[b], "y", true);
      ctx.strokeRect(Math.min(x0, x1), Math.min(y0, y1), Math.abs(x1 - x0), Math.abs(y1 - y0));
      ctx.fillText(z.name, Math.min(x0, x1) + 3 * devicePixelRatio, Math.min(y0, y1) + 12 * devicePixelRatio);
    }
    // the chosen poses' numbers, beside their markers
    ctx.fillStyle = "#111";
    for (const c of m.map.chosen) {
      ctx.fillText(c.pose, u.valToPos(c.q_deg[a], "x", true) + 7 * devicePixelRatio,
                   u.valToPos(c.q_deg[b], "y", true) - 7 * devicePixelRatio);
    }
    ctx.restore();
  }

  function hover(u) {
    const { left, top } = u.cursor;
    const info = el("acq-map-info");
    if (left === undefined || left < 0) { info.textContent = "hover a pose: its number and joint angles"; return; }
    const [a, b] = m.map.axes.map((j) => j - 1);
    let best = null, dist = 12;
    m.map.chosen.forEach((c) => {
      const d = Math.hypot(u.valToPos(c.q_deg[a], "x") - left, u.valToPos(c.q_deg[b], "y") - top);
      if (d < dist) { dist = d; best = c; }
    });
    if (best) {
      info.textContent = `pose ${best.pose} (${best.zone}; test ${best.tests.join(", ")}; ` +
        `${m.status[best.pose] || "pending"}): q1..q6 = ${vec(best.q_deg, 3)} deg`;
      return;
    }
    const q = m.map.candidates.q_deg;
    let near = -1; dist = 6;
    for (let i = 0; i < m.map.candidates.count; i++) {
      const d = Math.hypot(u.valToPos(q[a][i], "x") - left, u.valToPos(q[b][i], "y") - top);
      if (d < dist) { dist = d; near = i; }
    }
    info.textContent = near < 0 ? kappaAt(u, left, top) :
      `candidate: q1..q6 = ${vec(q.map((col) => col[near]), 3)} deg`;
  }

  async function loadMap(key, query) {
    m.key = key;
    m.rows = -1;
    el("acq-map-note").textContent = "drawing the zone map\u2026";
    try {
      const map = await get(`/api/acquire/map?${query}`);
      if (m.key !== key) return;
      m.map = map;
      m.status = {};
      build(map);
      el("acq-map-note").textContent = `${map.robot}: ${map.chosen.length} planned poses, ` +
        `${map.candidates.count} candidates passing the thresholds` +
        (map.grid ? `; background 1/kappa_F (dark 0, light ${Math.max(...map.grid.inv_kappa.map((r) => Math.max(...r))).toFixed(2)}) ` +
          `at ${map.grid.fixed_text} (${map.grid.rule_text})` : "") + (map.note ? `; ${map.note}` : "");
    } catch (err) {
      // a run directory appears whole a moment after its start: tried again next state
      if (m.key === key) {
        m.key = null;
        el("acq-map-note").textContent = err.status === 404 ? "zone map: waiting for the run " +
          "directory (it appears whole once the acquisition has checked its plan)" : `zone map: ${err.message}`;
      }
    }
  }

  function redraw() {
    if (!m.plot) return;
    m.plot.setData(data(), false);
    m.plot.redraw();
    const box = el("acq-map");
    box.dataset.done = Object.keys(m.status).filter((p) => m.status[p] === "done").join(",");
    box.dataset.current = m.current || "";
  }

  async function poses(run, rowsShown) {
    const p = await get(`/api/acquire/poses?run=${encodeURIComponent(run)}`);
    m.status = Object.fromEntries(p.poses.map((x) => [x.pose, x.status]));
    m.rows = rowsShown;
    el("acq-map").dataset.rows = String(p.rows_read);
    redraw();
  }

  // ---- the test being measured ----
  function showTrace(t) {
    el("acq-trace-test").textContent = t.test_id === null ? dash :
      `test ${t.test_id}, repeat ${t.repeat}, attempt ${t.attempt}, pose ${t.pose} (${t.phase})`;
    const w = t.result ? t.result.wrench : t.wrench;
    el("acq-trace-force").textContent = w ? vec(w.slice(0, 3), 1) : dash;
    el("acq-trace-moment").textContent = w ? vec(w.slice(3), 2) : dash;
    const last = t.t_s.length ? t.d_mm.map((c) => c[c.length - 1]) : null;
    el("acq-trace-reading").textContent = vec(last, 3);
    el("acq-trace-readings").textContent = String(t.t_s.length);
    el("acq-trace-d").textContent = t.result ? vec(t.result.d_mm, 3) : dash;
    el("acq-trace-r").textContent = t.result && t.result.r_mrad ? vec(t.result.r_mrad, 4) : dash;
    const cols = [t.t_s, ...t.d_mm];
    if (!m.trace) {
      m.trace = new uPlot({
        width: 520, height: 260, scales: { x: { time: false } },
        series: [{ label: "t (s)" },
          { label: "dx (mm)", stroke: "#1b9e77", width: 1.5, points: { show: true, size: 4 } },
          { label: "dy (mm)", stroke: "#d95f02", width: 1.5, points: { show: true, size: 4 } },
          { label: "dz (mm)", stroke: "#7570b3", width: 1.5, points: { show: true, size: 4 } }],
        axes: [{ label: "time since the load was applied (s, wall clock)" },
               { label: "displacement of P (mm)", size: 60 }],
      }, cols, el("acq-trace"));
    } else {
      m.trace.setData(cols);
    }
  }

  let busy = null, again = null;
  async function update(s) {  // one at a time; the newest state waiting is shown next
    if (busy) { again = s; return; }
    busy = true;
    try { await show(s); } finally {
      busy = null;
      if (again) { const next = again; again = null; update(next); }
    }
  }

  async function show(s) {
    const run = s.run_dir;
    if (m.key !== `run:${run}`) await loadMap(`run:${run}`, `run=${encodeURIComponent(run)}`);
    if (m.key !== `run:${run}` || !m.map) return;
    const current = s.running && s.live && s.live.pose !== undefined ? String(s.live.pose) : null;
    const rows = s.tests.length;
    if (rows !== m.rows) {
      try { await poses(run, rows); } catch (err) { el("acq-map-note").textContent = `poses: ${err.message}`; }
    }
    if (current !== m.current) { m.current = current; redraw(); }
    if (s.running || m.traced !== run) {  // a finished run's last test: read once
      try {
        showTrace(await get(`/api/acquire/trace?run=${encodeURIComponent(run)}`));
        m.traced = s.running ? null : run;
      } catch (err) { el("acq-trace-test").textContent = dash; }
    }
  }

  function preview(plan) {  // before a run: the plan's own map
    if (plan && m.key !== `plan:${plan}` && !(m.key || "").startsWith("run:")) {
      loadMap(`plan:${plan}`, `plan=${encodeURIComponent(plan)}`);
    }
  }

  window.acqMap = { update, preview, state: m };
})();
