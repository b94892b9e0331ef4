// The Analyze part's residual and validation plots, from what the analyze job wrote
// (GET /api/analyze/plots: residuals.csv, results.json). Shown for the run selected in
// #an-run whenever an analysis finishes (body[data-analyze] turns "done") or another run
// is selected; hidden while an analysis runs and after one fails. Hover a point for its values; drag to zoom, double-click to reset.
(function () {
  "use strict";
  const el = (id) => document.getElementById(id);
  const PALETTE = ["#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02",
                   "#a6761d", "#1f78b4", "#666666", "#b15928"];
  const ap = { res: null, val: null, data: null, asked: null };

  function fmt(v, digits) { return v === null || v === undefined ? "\u2013" : Number(v).toFixed(digits); }
  // residuals at the edge: m -> um, rad -> urad
  function micro(v, unit) { return v === null ? "\u2013" : `${(v * 1e6).toFixed(2)} ${unit === "rad" ? "\u00b5rad" : "\u00b5m"}`; }

  async function load(run) {
    const seq = ap.seq = (ap.seq || 0) + 1;  // only the newest request's answer is drawn
    ap.asked = run;
    const box = el("an-plots");
    if (!run) { box.hidden = true; return; }
    const r = await fetch(`/api/analyze/plots?run_dir=${encodeURIComponent(run)}`, { credentials: "same-origin" });
    const d = await r.json();
    if (ap.seq !== seq) return;
    if (!r.ok) {
      box.hidden = true;
      box.dataset.ready = "";
      el("an-plots-note").textContent = r.status === 404 ? "" : d.detail;
      return;
    }
    ap.data = d;
    box.hidden = false;
    const robust = d.robust && typeof d.robust === "object" ? d.robust.method || "robust" : d.robust || "none";
    el("an-plots-note").textContent = `plots of ${run}/analysis as written (method ${d.method}, ` +
      `robust ${robust}): residuals.csv and results.json`;
    residualPlot(d);
    validationPlot(d);
    box.dataset.run = run;
    box.dataset.ready = String(Date.now());
  }

  function residualPlot(d) {
    const res = d.residuals;
    const n = res.studentized.length;
    const x = Array.from({ length: n }, (_, i) => i + 1);
    const poses = [...new Set(res.pose)];
    const own = poses.length <= PALETTE.length;  // a series per pose, else per colour
    const group = Object.fromEntries(poses.map((p, i) => [p, i % PALETTE.length]));
    const nSeries = own ? poses.length : Math.min(PALETTE.length, poses.length);
    const cols = [x];
    const series = [{ label: "row" }];
    for (let g = 0; g < nSeries; g++) {
      cols.push(res.studentized.map((t, i) => (group[res.pose[i]] === g ? t : null)));
      const label = own ? `pose ${poses[g]}` : `poses ${poses.filter((p) => group[p] === g).slice(0, 3).join(", ")}\u2026`;
      series.push({ label, paths: () => null, stroke: PALETTE[g],
                    points: { show: true, size: 6, fill: PALETTE[g], stroke: PALETTE[g] } });
    }
    cols.push(res.studentized.map((t, i) => (res.outlier[i] ? t : null)));
    series.push({ label: "outlier (beyond the threshold)", paths: () => null, stroke: "#b00020",
                  points: { show: true, size: 13, fill: "rgba(0,0,0,0)", stroke: "#b00020", width: 2 } });
    cols.push(res.studentized.map((t, i) => (res.set_aside[i] ? t : null)));
    series.push({ label: "set aside by the sequential test", paths: () => null, stroke: "#e08a00",
                  points: { show: true, size: 17, fill: "rgba(0,0,0,0)", stroke: "#e08a00", width: 1.5 } });
    const th = d.threshold;
    if (th !== null) {
      cols.push(x.map(() => th), x.map(() => -th));
      series.push({ label: `+threshold ${th.toFixed(3)}`, stroke: "#b00020", dash: [6, 4], width: 1.2, points: { show: false } },
                  { label: `\u2212threshold`, stroke: "#b00020", dash: [6, 4], width: 1.2, points: { show: false } });
    }
    let worst = -1;
    res.studentized.forEach((t, i) => { if (t !== null && (worst < 0 || Math.abs(t) > Math.abs(res.studentized[worst]))) worst = i; });
    el("an-res-max").textContent = worst < 0 ? "no studentized residuals" :
      `largest |studentized residual| ${Math.abs(res.studentized[worst]).toFixed(3)} ` +
      `(row ${worst + 1}: test ${res.test[worst]}, pose ${res.pose[worst]}, ${res.component[worst]}); ` +
      (th === null ? "no threshold given" : `outlier threshold ${th.toFixed(3)}`) +
      `; ${res.outlier.filter((v) => v).length} outlier(s); ${d.residuals_shown}`;
    el("an-res-fig").dataset.points = String(n);
    el("an-res-fig").dataset.max = worst < 0 ? "" : String(Math.abs(res.studentized[worst]));
    const opts = {
      width: 560, height: 320, scales: { x: { time: false } }, series, legend: { live: false },
      cursor: { drag: { x: true, y: true, uni: 30 }, points: { show: false } },
      axes: [{ label: "residual row of residuals.csv (test by test, component by component)" },
             { label: "studentized residual", size: 55 }],
      hooks: { setCursor: [(u) => {
        const i = u.cursor.idx;
        el("an-res-info").textContent = i === null || i === undefined ? "hover a point for its values" :
          `row ${i + 1}: test ${res.test[i]}, pose ${res.pose[i]}, ${res.component[i]}: studentized ` +
          `${fmt(res.studentized[i], 3)}, residual ${micro(res.residual[i], res.unit[i])} ` +
          `(sigma ${micro(res.sigma[i], res.unit[i])})` + (res.outlier[i] ? ", OUTLIER" : "") +
          (res.set_aside[i] ? ", set aside" : "") +
          (res.weight[i] === null ? "" : `, robust weight ${fmt(res.weight[i], 3)}`);
      }] },
    };
    if (ap.res) ap.res.destroy();
    ap.res = new uPlot(opts, cols, el("an-res-fig"));
  }

  function validationPlot(d) {
    const v = d.validation;
    const box = el("an-val-fig");
    if (ap.val) { ap.val.destroy(); ap.val = null; }
    if (!v.length) {
      el("an-val-max").textContent = "no held-out validation in this analysis";
      box.dataset.points = "0";
      return;
    }
    const x = v.map((_, i) => i + 1);
    const total = v.map((r) => r.rms_normalized_total);
    const cols = [x, total, v.map((r) => r.limit_normalized_total),
                  v.map((r) => r.rms_normalized), v.map((r, i) => (r.beyond_limit ? total[i] : null))];
    const series = [{ label: "held-out pose" },
      { label: "RMS error / total uncertainty", paths: () => null, stroke: "#24344d",
        points: { show: true, size: 9, fill: "#24344d", stroke: "#24344d" } },
      { label: "limit (1 % family-wise)", stroke: "#b00020", dash: [6, 4], width: 1.5, points: { show: false } },
      { label: "RMS error / noise sigma", paths: () => null, stroke: "#7570b3",
        points: { show: true, size: 8, fill: "rgba(0,0,0,0)", stroke: "#7570b3", width: 1.5 } },
      { label: "beyond the limit", paths: () => null, stroke: "#b00020",
        points: { show: true, size: 16, fill: "rgba(0,0,0,0)", stroke: "#b00020", width: 2.5 } }];
    const beyond = v.filter((r) => r.beyond_limit).map((r) => r.held_out_pose);
    el("an-val-max").textContent = `${v.length} held-out pose(s) (${d.validation_listed || ""}); ` +
      (beyond.length ? `beyond the limit: ${beyond.join(", ")}` : "none beyond the limit");
    box.dataset.points = String(v.length);
    box.dataset.beyond = beyond.join(",");
    const opts = {
      width: 500, height: 320, series, legend: { live: false },
      scales: { x: { time: false, range: (u, lo, hi) => (lo <= 1 && hi >= v.length ?
                  [0.5, v.length + 0.5] : [lo, hi]) },
                y: { range: (u, lo, hi) => [0, Math.max(hi, 1) * 1.1] } },
      cursor: { points: { show: false } },
      axes: [{ label: "held-out pose", values: (u, ticks) => ticks.map((t) => (Number.isInteger(t) && v[t - 1] ? v[t - 1].held_out_pose : "")) },
             { label: "normalized prediction error (RMS)", size: 55 }],
      hooks: { setCursor: [(u) => {
        const i = u.cursor.idx;
        const r = i === null || i === undefined ? null : v[i];
        el("an-val-info").textContent = !r ? "hover a pose for its values" :
          `pose ${r.held_out_pose} (${r.n_tests} tests): RMS error / total uncertainty ` +
          `${fmt(r.rms_normalized_total, 3)}, limit ${fmt(r.limit_normalized_total, 3)}, p ` +
          `${fmt(r.p_value_total, 4)}; RMS error / noise ${fmt(r.rms_normalized, 3)}; RMS ` +
          `${micro(r.rms_translation_m, "m")}, ${micro(r.rms_rotation_rad, "rad")}` +
          (r.beyond_limit ? "; BEYOND THE LIMIT" : "");
      }] },
    };
    ap.val = new uPlot(opts, cols, box);
  }

  function watch() {
    const sel = el("an-run");
    sel.addEventListener("change", () => load(sel.value).catch(() => {}));
    // an analysis finished (plan.js sets body[data-analyze]), or the view got its runs
    new MutationObserver(() => {
      const b = document.body.dataset;
      if (b.analyze === "done") load(sel.value).catch(() => {});
      // a new analysis: the plots of the previous one are not its (hidden until it is done)
      if (b.analyze === "running") { ap.seq = (ap.seq || 0) + 1; el("an-plots").hidden = true; }
    }).observe(document.body, { attributes: true, attributeFilter: ["data-analyze"] });
    new MutationObserver(() => {
      if (document.body.dataset.planview === "ready" && ap.asked === null) load(sel.value).catch(() => {});
    }).observe(document.body, { attributes: true, attributeFilter: ["data-planview"] });
  }

  window.anPlots = { load, state: ap };
  watch();
})();
