// campaign gui, the Use view: K_X and the deflection at a pose (joint sliders), the
// compensation of a path, and the comparison of two analyses. Every number comes from a
// job of the server (POST /api/jobs/stiffness, /compensate, /compare; SI in the bodies);
// the page converts only at its edge: deg for joints, mm and mrad, N/mm and N m/mrad, kN m/rad.
(() => {
"use strict";

const use = { csrf: null, header: null, robot: null, timer: null, inflight: false,
              dirty: false, calls: 0, plot: null };
const DEG = Math.PI / 180;
const WRENCH = [["fx", "N"], ["fy", "N"], ["fz", "N"], ["mx", "N m"], ["my", "N m"], ["mz", "N m"]];

function u$(id) { return document.getElementById(id); }

function fmt(x, digits = 5) {
  if (x === null || x === undefined || !Number.isFinite(x)) return "\u2014";
  if (x === 0) return "0";
  return Number(x.toPrecision(digits)).toString();
}

async function useGet(url) {
  const r = await fetch(url, { credentials: "same-origin" });
  if (!r.ok) throw new Error(`${url}: ${r.status} ${(await r.text()).slice(0, 300)}`);
  return r.json();
}

async function usePost(url, body) {
  const r = await fetch(url, { method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", [use.header]: use.csrf },
    body: JSON.stringify(body) });
  const doc = await r.json().catch(() => ({ detail: `${r.status}` }));
  if (!r.ok) throw new Error(typeof doc.detail === "string" ? doc.detail : JSON.stringify(doc.detail));
  return doc;
}

function wrenchInputs(box, prefix, values) {
  WRENCH.forEach(([name, unit], i) => {
    const l = document.createElement("label");
    l.innerHTML = `<span>${name} (${unit})</span><input type="number" id="${prefix}-${name}" step="any">`;
    box.appendChild(l);
    l.querySelector("input").value = String(values[i]);
  });
}

function wrenchOf(prefix) {
  return WRENCH.map(([name]) => {
    const v = Number(u$(`${prefix}-${name}`).value);
    if (!Number.isFinite(v)) throw new Error(`wrench ${name}: not a number`);
    return v;
  });
}

function fillSelect(sel, items, keep) {
  const old = keep ? sel.value : null;
  sel.innerHTML = "";
  for (const [value, text] of items) {
    const o = document.createElement("option"); o.value = value; o.textContent = text;
    sel.appendChild(o);
  }
  if (old && items.some(([v]) => v === old)) sel.value = old;
}

// ---- stiffness at a pose -------------------------------------------------------------

async function loadRobot() {
  const name = u$("use-robot").value;
  u$("use-error").textContent = "";
  const r = await usePost("/api/jobs/robots", { name });
  use.robot = r;
  u$("use-robot-info").textContent = `${r.name}: ${r.joints} joints; angles in the model ` +
    `convention (${r.convention}), limits from ${r.source_file ? r.source_file.split("/").pop() : "the model"}`;
  const box = u$("use-joints");
  for (const el of box.querySelectorAll("label")) el.remove();
  // where the sliders start: the first zone's centre, other joints a quarter of the way
  // from the middle of their range to its top (off the wrist singularity at 0)
  const start = r.lower_rad.map((lo, j) => (lo + r.upper_rad[j]) / 2 + (r.upper_rad[j] - lo) / 8);
  const zone = (r.zones || [])[0];
  if (zone) {
    for (const [key, [a, b]] of Object.entries(zone.ranges_rad)) start[Number(key.slice(1)) - 1] = (a + b) / 2;
  }
  for (let j = 0; j < r.joints; j++) {
    const lo = Number((r.lower_rad[j] / DEG).toFixed(6)), hi = Number((r.upper_rad[j] / DEG).toFixed(6));
    const l = document.createElement("label");
    l.className = "slider";
    l.innerHTML = `<span>q${j + 1} (deg) [${fmt(lo)}, ${fmt(hi)}]</span>` +
      `<input type="range" id="q${j + 1}" min="${lo}" max="${hi}" step="0.5">` +
      `<input type="number" id="q${j + 1}-deg" min="${lo}" max="${hi}" step="any" title="q${j + 1} (deg), within [${fmt(lo)}, ${fmt(hi)}]">`;
    box.appendChild(l);
    const s = l.querySelector("input[type=range]"), n = l.querySelector("input[type=number]");
    s.value = String(Math.round(2 * start[j] / DEG) / 2);
    n.value = s.value;
    s.addEventListener("input", () => { n.value = s.value; scheduleStiffness(); });
    n.addEventListener("change", () => {
      let v = Number(n.value);
      if (!Number.isFinite(v)) v = Number(s.value);
      const clamped = Math.min(Math.max(v, lo), hi);  // the limits are enforced here too
      n.value = String(clamped);
      s.value = String(clamped);
      u$("use-limit").textContent = clamped !== v ? `q${j + 1} held at its limit ${fmt(clamped)} deg` : "";
      scheduleStiffness();
    });
  }
  const pendant = document.createElement("label");
  pendant.innerHTML = `<span>pendant (controller) convention</span><output id="use-pendant"></output>`;
  box.appendChild(pendant);
  scheduleStiffness();
}

function showPendant(qDeg) {
  // q_ctrl = (diag(sign) + coupling) q_model + offset, as the model file defines it
  const r = use.robot;
  const out = qDeg.map((_, i) => r.controller_offset_rad[i] / DEG + qDeg.reduce(
    (acc, q, j) => acc + ((i === j ? r.controller_sign[i] : 0) + r.controller_coupling[i][j]) * q, 0));
  u$("use-pendant").textContent = out.map((v, i) => `A${i + 1} ${fmt(v)}`).join(", ") + " deg";
}

function poseDeg() {
  return Array.from({ length: use.robot.joints }, (_, j) => Number(u$(`q${j + 1}-deg`).value));
}

function scheduleStiffness() {
  clearTimeout(use.timer);
  use.timer = setTimeout(runStiffness, 60);
}

async function runStiffness() {
  if (use.inflight) { use.dirty = true; return; }
  use.inflight = true; use.dirty = false;
  const qDeg = poseDeg();
  showPendant(qDeg);
  let wrenchShown = null;
  const view = u$("view-use");
  view.dataset.busy = "1";
  try {
    // the limits in deg are rounded on the page: the angles sent are held inside the model's
    const lo = use.robot.lower_rad, hi = use.robot.upper_rad;
    const body = { robot: u$("use-robot").value,
                   q_rad: qDeg.map((v, j) => Math.min(Math.max(v * DEG, lo[j]), hi[j])),
                   wrench_N_Nm: wrenchOf("use-w") };
    wrenchShown = body.wrench_N_Nm;
    const res = await usePost("/api/jobs/stiffness", body);
    u$("use-error").textContent = "";
    showStiffness(res);
  } catch (err) {
    u$("use-error").textContent = String(err.message || err);
    showStiffness(null);
  } finally {
    use.inflight = false;
    use.calls += 1;
    view.dataset.shownQ = JSON.stringify(qDeg);
    view.dataset.shownW = JSON.stringify(wrenchShown);
    view.dataset.busy = "";
    if (use.dirty) runStiffness();
  }
}

function block(id, K, off, scale) {
  const tb = u$(id).querySelector("tbody");
  tb.innerHTML = "";
  for (let i = 0; i < 3; i++) {
    const tr = document.createElement("tr");
    for (let j = 0; j < 3; j++) {
      const td = document.createElement("td");
      td.id = `${id}-${i}${j}`;
      td.textContent = K ? fmt(K[off + i][off + j] * scale) : "undefined";
      tr.appendChild(td);
    }
    tb.appendChild(tr);
  }
}

function showStiffness(res) {
  const undef = res && res.K_X === null;
  u$("use-undefined").hidden = !undef;
  u$("use-undefined").textContent = undef ? `K_X is undefined at this pose: ${res.undefined.K_X}` : "";
  const K = res && !undef ? res.K_X : null;
  block("use-kx-t", K, 0, 1e-3);   // N/m -> N/mm
  block("use-kx-r", K, 3, 1e-3);   // N m/rad -> N m/mrad
  const tb = u$("use-defl").querySelector("tbody");
  tb.innerHTML = "";
  if (!res) return;
  const d = res.deflection_nonlinear_m_rad, un = res.uncertainty;
  ["dx", "dy", "dz", "rx", "ry", "rz"].forEach((name, i) => {
    const unit = i < 3 ? "mm" : "mrad";
    const band = un ? `[${fmt(1e3 * un.deflection_nonlinear_lo95_m_rad[i])}, ${fmt(1e3 * un.deflection_nonlinear_hi95_m_rad[i])}]`
                    : "no covariance in the model";
    const tr = document.createElement("tr");
    tr.innerHTML = `<td>${name}</td><td id="use-d-${name}">${fmt(1e3 * d[i])}</td><td id="use-d-${name}-95">${band}</td><td>${unit}</td>`;
    tb.appendChild(tr);
  });
  u$("use-status").textContent = `k: ${res.joint_stiffness_source}; wrench ${res.wrench_N_Nm.map((v) => fmt(v)).join(", ")} (N, N m) at P`;
}

// ---- compensation of a path ----------------------------------------------------------

function parseCSV(text) {
  const lines = text.trim().split(/\r?\n/);
  const head = lines[0].split(",");
  const cols = Object.fromEntries(head.map((h) => [h, []]));
  for (const line of lines.slice(1)) {
    line.split(",").forEach((v, i) => cols[head[i]].push(Number(v)));
  }
  return cols;
}

function fileLink(path) {
  const a = document.createElement("a");
  const program = /\.(src|dat|mod|script)$/i.test(path);
  a.href = (program ? "/api/use/program?path=" : "/api/runs/file?path=") + encodeURIComponent(path);
  a.textContent = path; a.target = "_blank";
  return a;
}

async function runCompensation() {
  u$("comp-error").textContent = "";
  u$("comp-run").disabled = true;
  const view = u$("view-use");
  view.dataset.comp = "running";
  try {
    const res = await usePost("/api/jobs/compensate", {
      robot: u$("comp-robot").value, path: u$("comp-path").value, out: u$("comp-out").value.trim(),
      wrench_N_Nm: wrenchOf("comp-w"), force: u$("comp-force").checked });
    const csv = res.files.find((f) => f.endsWith("compensated.csv"));
    const table = parseCSV(await (await fetch("/api/runs/file?path=" + encodeURIComponent(csv))).text());
    showCompensation(res, table);
    view.dataset.comp = "done";
  } catch (err) {
    u$("comp-error").textContent = String(err.message || err);
    view.dataset.comp = "error";
  } finally {
    u$("comp-run").disabled = false;
  }
}

function showCompensation(res, t) {
  u$("comp-result").hidden = false;
  const tb = u$("comp-summary").querySelector("tbody");
  const tr = res.translation_m, rr = res.rotation_rad;
  const rows = [
    ["points", "comp-points", String(res.points), ""],
    ["max |dp| before (predicted)", "comp-before-max", fmt(1e3 * tr.before.max), "mm"],
    ["max |dp| before, 95 % upper bound", "comp-before-hi", fmt(1e3 * tr.before_upper95_max), "mm"],
    ["max |dp| after compensation (model residual)", "comp-after-max", fmt(1e3 * tr.after.max), "mm"],
    ["max |dp| after, 95 % upper bound", "comp-after-hi", fmt(1e3 * tr.after_upper95_max), "mm"],
    ["max |dr| before (predicted)", "comp-rbefore-max", fmt(1e3 * rr.before.max), "mrad"],
    ["worst point (line of the path file)", "comp-worst", String(res.worst_point.line), ""],
  ];
  tb.innerHTML = rows.map(([a, id, v, unit]) => `<tr><th>${a}</th><td id="${id}">${v}</td><td>${unit}</td></tr>`).join("");
  const files = u$("comp-files");
  files.innerHTML = "";
  for (const f of res.files) { files.appendChild(fileLink(f)); files.appendChild(document.createTextNode(" ")); }
  const x = t.dx_mm.map((_, i) => i + 1);
  const data = [x];
  const series = [{ label: "point" }];
  const colours = ["#c0392b", "#2471a3", "#229954"];
  const bands = [];
  ["dx", "dy", "dz"].forEach((c, i) => {
    const hasBand = t[`${c}_lo95_mm`] && t[`${c}_lo95_mm`].every(Number.isFinite);
    data.push(t[`${c}_mm`]);
    series.push({ label: `${c} (mm)`, stroke: colours[i], width: 2 });
    if (hasBand) {
      const k = data.length;
      data.push(t[`${c}_hi95_mm`], t[`${c}_lo95_mm`]);
      series.push({ label: `${c} 95 % hi (mm)`, stroke: colours[i], dash: [4, 4], width: 1 },
                  { label: `${c} 95 % lo (mm)`, stroke: colours[i], dash: [4, 4], width: 1 });
      bands.push({ series: [k, k + 1], fill: colours[i] + "33" });
    }
  });
  const box = u$("comp-fig");
  if (use.plot) use.plot.destroy();
  box.innerHTML = "";
  use.plot = new uPlot({ width: 760, height: 300, series, bands, legend: { live: true },
                         scales: { x: { time: false } },
                         axes: [{ label: "path point" }, { label: "deflection (mm)", size: 60 }] }, data, box);
}

// ---- compare two analyses ------------------------------------------------------------

async function runCompare() {
  u$("cmp-error").textContent = "";
  const view = u$("view-use");
  view.dataset.cmp = "running";
  try {
    const res = await usePost("/api/jobs/compare", { a: u$("cmp-a").value, b: u$("cmp-b").value,
                                                     alpha: Number(u$("cmp-alpha").value) });
    u$("cmp-level").textContent = `${res.robot}: intervals at ${res.interval_level_text}; ` +
      `critical |z| ${fmt(res.critical_z, 4)}`;
    const tb = u$("cmp-table").querySelector("tbody");
    tb.innerHTML = res.joints.map((r) => `<tr id="cmp-row-${r.joint}"><td>k${r.joint}</td>` +
      `<td>${fmt(r.k_A_Nm_per_rad / 1e3)}</td><td>${fmt(r.k_B_Nm_per_rad / 1e3)}</td>` +
      `<td class="dk">${fmt(r.difference_Nm_per_rad / 1e3)}</td>` +
      `<td class="iv">[${fmt(r.interval_difference_Nm_per_rad[0] / 1e3)}, ${fmt(r.interval_difference_Nm_per_rad[1] / 1e3)}]</td>` +
      `<td>${fmt(r.z, 4)}</td><td class="verdict">${r.verdict}${r.note ? " (" + r.note + ")" : ""}</td></tr>`).join("");
    u$("cmp-table").hidden = false;
    view.dataset.cmp = "done";
  } catch (err) {
    u$("cmp-error").textContent = String(err.message || err);
    u$("cmp-table").hidden = true;
    view.dataset.cmp = "error";
  }
}

// ---- start -----------------------------------------------------------------------------

async function refreshFiles() {
  const f = await useGet("/api/use/files");
  const robots = (await robotChoices()).map((c) => [c.value, c.label]);  // robots.js
  const first = !u$("use-robot").options.length;
  fillSelect(u$("use-robot"), robots, true);
  if (first && f.builtin.includes("kr240-2")) u$("use-robot").value = "kr240-2";
  const models = [...f.models.map((m) => [m, m]), ...f.builtin.map((n) => [n, `${n} (built-in, nominal k)`])];
  fillSelect(u$("comp-robot"), models, true);
  fillSelect(u$("comp-path"), f.paths.map((p) => [p, p]), true);
  fillSelect(u$("cmp-a"), f.analyses.map((p) => [p, p]), true);
  fillSelect(u$("cmp-b"), f.analyses.map((p) => [p, p]), true);
  if (f.analyses.length > 1 && u$("cmp-a").value === u$("cmp-b").value) u$("cmp-b").value = f.analyses[1];
}

async function startUse() {
  const session = await useGet("/api/session");
  use.csrf = session.csrf_token; use.header = session.csrf_header;
  wrenchInputs(u$("use-wrench"), "use-w", [0, 0, -2000, 0, 200, 0]);
  wrenchInputs(u$("comp-wrench"), "comp-w", [500, 0, -1000, 0, 20, 0]);
  await refreshFiles();
  u$("use-robot").addEventListener("change", () => loadRobot().catch((e) => { u$("use-error").textContent = String(e.message || e); }));
  for (const [name] of WRENCH) u$(`use-w-${name}`).addEventListener("change", scheduleStiffness);
  u$("comp-run").addEventListener("click", runCompensation);
  u$("cmp-run").addEventListener("click", runCompare);
  u$("tab-use").addEventListener("click", () => refreshFiles().catch(() => {}));
  await loadRobot();
  u$("view-use").dataset.ready = "1";
}

// for the tests and the screenshot script: what the page shows, nothing to change it
window.useView = { poseDeg, wrench: () => wrenchOf("use-w"), state: use };
startUse().catch((err) => { u$("use-error").textContent = String(err.message || err); });
})();
