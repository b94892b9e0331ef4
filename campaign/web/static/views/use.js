// campaign gui, the Use view: K_X and the deflection at a pose (joint sliders, in the model
// or the pendant convention), the deflection along a path with its band, the placement
// search (a queued job, its progress from server-sent events), the compensation of a path
// the comparison of two analyses and the export to a simulator. Every number comes from a job of the server (POST
// /api/jobs/stiffness, /place, /compensate, /compare, /export, /api/use/deflection; SI in the bodies
// but place's, in the command line's mm and deg); the page converts only at its edge: deg
// for joints, mm and mrad, N/mm and N m/mrad, kN m/rad. A job's refusal is shown in the
// page's terms: the command-line options it names become the labels of this page's fields.
(() => {
"use strict";

const use = { csrf: null, header: null, robot: null, timer: null, inflight: false,
              dirty: false, calls: 0, plot: null, pdPlot: null, job: null, pendant: false };
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

async function post(url, body) {
  const r = await fetch(url, { method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", [use.header]: use.csrf },
    body: JSON.stringify(body) });
  const doc = await r.json().catch(() => ({ detail: `${r.status}` }));
  return [r.status, doc];
}

async function usePost(url, body) {
  const [status, doc] = await post(url, body);
  if (status >= 400) throw jobError(doc, status);
  return doc;
}

// A queued job (202): app.js's followJob with this view's POST; use.job is its id while
// it runs (the Cancel button's).
async function runJob(url, body, onProgress) {
  try {
    return await followJob(post, url, body, onProgress, (id) => { use.job = id; });
  } finally {
    use.job = null;
  }
}

// a job's refusal in the form's terms: app.js's shared helpers
const labelsOf = fieldLabels;
const inTerms = inFormTerms;

// a job's own sentence (a warning of placement.json) in this page's terms: a command-line
// option --x-mm is the field x_mm of the job's options, shown by its label
function optionsAsLabels(text, labels) {
  return String(text).replace(/--([a-z][a-z0-9-]*)/g, (all, name) => {
    const label = labels[name.replace(/-/g, "_")];
    return label ? `\u201c${label}\u201d` : all;
  });
}

// the error beside its field (and in the form's error line); false when no field shows it
function showFieldError(form, err, errorLine) {
  for (const m of form.querySelectorAll(".use-msg")) m.textContent = "";
  const text = inTerms(err, labelsOf(form));
  errorLine.textContent = text;
  const msg = err.field && form.querySelector(`.use-msg[data-for="${err.field}"]`);
  if (msg) msg.textContent = text;
  return Boolean(msg);
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
  // where the sliders start: the first zone's centre, other joints a quarter of the way
  // from the middle of their range to its top (off the wrist singularity at 0)
  const start = r.lower_rad.map((lo, j) => (lo + r.upper_rad[j]) / 2 + (r.upper_rad[j] - lo) / 8);
  const zone = (r.zones || [])[0];
  if (zone) {
    for (const [key, [a, b]] of Object.entries(zone.ranges_rad)) start[Number(key.slice(1)) - 1] = (a + b) / 2;
  }
  buildSliders(start.map((v) => Math.round(2 * v / DEG) / 2));
  scheduleStiffness();
}

// ---- the two conventions: model q (deg) and pendant A = (diag(sign) + coupling) q + offset

function ctrlMatrix() {
  const r = use.robot;
  return r.controller_sign.map((sg, i) => r.controller_coupling[i].map((c, j) => (i === j ? sg : 0) + c));
}

function toCtrl(q) {
  const off = use.robot.controller_offset_rad.map((v) => v / DEG);
  return ctrlMatrix().map((row, i) => off[i] + row.reduce((a, m, j) => a + m * q[j], 0));
}

function fromCtrl(a) {
  // solve M q = a - offset (Gaussian elimination with partial pivoting; M is 6x6)
  const M = ctrlMatrix().map((row) => row.slice());
  const off = use.robot.controller_offset_rad.map((v) => v / DEG);
  const b = a.map((v, i) => v - off[i]);
  const n = b.length;
  for (let c = 0; c < n; c++) {
    let p = c;
    for (let i = c + 1; i < n; i++) if (Math.abs(M[i][c]) > Math.abs(M[p][c])) p = i;
    [M[c], M[p]] = [M[p], M[c]]; [b[c], b[p]] = [b[p], b[c]];
    for (let i = c + 1; i < n; i++) {
      const f = M[i][c] / M[c][c];
      for (let j = c; j < n; j++) M[i][j] -= f * M[c][j];
      b[i] -= f * b[c];
    }
  }
  const q = new Array(n).fill(0);
  for (let i = n - 1; i >= 0; i--) {
    let acc = b[i];
    for (let j = i + 1; j < n; j++) acc -= M[i][j] * q[j];
    q[i] = acc / M[i][i];
  }
  return q.map((v) => Number(v.toFixed(9)));  // the solve's rounding, not a new angle
}

function modelLimits() {
  const r = use.robot;
  return [r.lower_rad.map((v) => Number((v / DEG).toFixed(6))), r.upper_rad.map((v) => Number((v / DEG).toFixed(6)))];
}

// the slider ranges of the shown convention: the model's limits, or their image on the
// pendant (interval sum of each row of M over the limits' box, plus the offset)
function shownLimits() {
  const [lo, hi] = modelLimits();
  if (!use.pendant) return [lo, hi];
  const off = use.robot.controller_offset_rad.map((v) => v / DEG);
  const M = ctrlMatrix();
  const a = M.map((row, i) => off[i] + row.reduce((acc, m, j) => acc + Math.min(m * lo[j], m * hi[j]), 0));
  const b = M.map((row, i) => off[i] + row.reduce((acc, m, j) => acc + Math.max(m * lo[j], m * hi[j]), 0));
  return [a.map((v) => Number(v.toFixed(6))), b.map((v) => Number(v.toFixed(6)))];
}

function buildSliders(qModel) {
  const r = use.robot;
  const box = u$("use-joints");
  for (const el of box.querySelectorAll("label")) el.remove();
  u$("use-joints-legend").textContent = use.pendant ?
    "Joint angles (deg, pendant convention A1..A6; slider range = the model's limits on the pendant)" :
    "Joint angles (deg, model convention; slider range = the model's limits)";
  const [lo, hi] = shownLimits();
  const shown = use.pendant ? toCtrl(qModel) : qModel;
  for (let j = 0; j < r.joints; j++) {
    const name = use.pendant ? `A${j + 1}` : `q${j + 1}`;
    const l = document.createElement("label");
    l.className = "slider";
    l.innerHTML = `<span>${name} (deg) [${fmt(lo[j])}, ${fmt(hi[j])}]</span>` +
      `<input type="range" id="q${j + 1}" min="${lo[j]}" max="${hi[j]}" step="0.5">` +
      `<input type="number" id="q${j + 1}-deg" min="${lo[j]}" max="${hi[j]}" step="any" title="${name} (deg), within [${fmt(lo[j])}, ${fmt(hi[j])}]">`;
    box.appendChild(l);
    const sl = l.querySelector("input[type=range]"), n = l.querySelector("input[type=number]");
    n.value = String(Number(shown[j].toFixed(9)));
    sl.value = n.value;
    sl.addEventListener("input", () => { n.value = sl.value; enforceLimits(j); scheduleStiffness(); });
    n.addEventListener("change", () => {
      let v = Number(n.value);
      if (!Number.isFinite(v)) v = Number(sl.value);
      const clamped = Math.min(Math.max(v, lo[j]), hi[j]);  // the limits are enforced here too
      n.value = String(clamped);
      sl.value = String(clamped);
      u$("use-limit").textContent = clamped !== v ? `${name} held at its limit ${fmt(clamped)} deg` : "";
      enforceLimits(j);
      scheduleStiffness();
    });
  }
  const pendant = document.createElement("label");
  pendant.innerHTML = use.pendant ? `<span>model convention</span><output id="use-pendant"></output>` :
    `<span>pendant (controller) convention</span><output id="use-pendant"></output>`;
  box.appendChild(pendant);
}

// pendant mode: the pendant's box is wider than the model's limits when joints are
// coupled; the pose is held inside the model's limits, and the sliders show where
function enforceLimits(j) {
  if (!use.pendant) return;
  const [lo, hi] = modelLimits();
  const q = fromCtrl(shownValues());
  const held = q.map((v, i) => Math.min(Math.max(v, lo[i]), hi[i]));
  if (held.every((v, i) => v === q[i])) return;
  const a = toCtrl(held);
  a.forEach((v, i) => {
    u$(`q${i + 1}-deg`).value = String(Number(v.toFixed(9)));
    u$(`q${i + 1}`).value = String(v);
  });
  u$("use-limit").textContent = `A${j + 1} held: the pose stays inside the model's joint limits`;
}

function shownValues() {
  return Array.from({ length: use.robot.joints }, (_, j) => Number(u$(`q${j + 1}-deg`).value));
}

function setConvention(pendant) {
  const q = poseDeg();
  use.pendant = pendant;
  buildSliders(q);
  scheduleStiffness();
}

function showPendant(qDeg) {
  // the other convention than the sliders': the pendant's A (the model file's transform),
  // or the model's q when the sliders are the pendant's
  const out = use.pendant ? qDeg : toCtrl(qDeg);
  const name = use.pendant ? "q" : "A";
  u$("use-pendant").textContent = out.map((v, i) => `${name}${i + 1} ${fmt(v)}`).join(", ") + " deg";
}

// the pose in the model convention (deg), whatever the sliders show
function poseDeg() {
  const shown = shownValues();
  return use.pendant ? fromCtrl(shown) : shown;
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
  // a robot program is for the controller: the link saves the file under its own name
  if (program) a.download = path.split("/").pop();
  return a;
}

async function runCompensation() {
  u$("comp-error").textContent = "";
  u$("comp-result").hidden = true;  // the previous compensation's: shown again only by this one
  u$("comp-run").disabled = true;
  const view = u$("view-use");
  view.dataset.comp = "running";
  const bar = u$("comp-progress");
  bar.hidden = false; bar.removeAttribute("value");
  try {
    const res = await runJob("/api/jobs/compensate", {
      robot: u$("comp-robot").value, path: u$("comp-path").value, out: u$("comp-out").value.trim(),
      wrench_N_Nm: wrenchOf("comp-w"), force: u$("comp-force").checked },
      (j) => { u$("comp-text").textContent = j.text; });
    const csv = res.files.find((f) => f.endsWith("compensated.csv"));
    const table = parseCSV(await (await fetch("/api/runs/file?path=" + encodeURIComponent(csv))).text());
    showCompensation(res, table);
    view.dataset.comp = "done";
  } catch (err) {
    u$("comp-error").textContent = inTerms(err, { force: "Replace its files", out: "Output directory",
                                                  path: "Path CSV", robot: "Robot model", wrench_N_Nm: "wrench" });
    view.dataset.comp = "error";
  } finally {
    u$("comp-run").disabled = false;
    bar.hidden = true;
  }
}

// ---- deflection along a path (no compensation, nothing written) ----------------------

const PD_LIMIT = 2000000;  // characters of an uploaded path, as the server's limit

async function runDeflection() {
  const view = u$("view-use");
  u$("pd-error").textContent = "";
  view.dataset.pd = "running";
  try {
    const body = { robot: u$("pd-robot").value, controller_angles: u$("pd-pendant").checked };
    if (u$("pd-constant").checked) body.wrench_N_Nm = wrenchOf("pd-w");
    const file = u$("pd-file").files[0];
    if (file) {
      if (file.size > PD_LIMIT) throw new Error(`${file.name}: ${file.size} bytes, above the limit of ${PD_LIMIT} for an upload`);
      body.upload_name = file.name;
      body.upload_text = await file.text();
    } else {
      body.path = u$("pd-path").value;
    }
    const res = await usePost("/api/use/deflection", body);
    showDeflection(res);
    view.dataset.pd = "done";
  } catch (err) {
    u$("pd-error").textContent = inTerms(err, { wrench_N_Nm: "constant wrench", controller_angles: "pendant angles" });
    u$("pd-result").hidden = true;
    view.dataset.pd = "error";
  }
}

function showDeflection(res) {
  u$("pd-result").hidden = false;
  const band = res.lo95_m_rad !== null;
  const rows = [
    ["points", "pd-points", String(res.points), ""],
    ["max |dp| (predicted)", "pd-max", fmt(1e3 * res.max_norm_p_m), "mm"],
    ["max |dp|, 95 % upper bound", "pd-max-hi", band ? fmt(1e3 * Math.max(...res.norm_p_upper95_m)) : "no covariance in the model", band ? "mm" : ""],
    ["worst point (line of the path file)", "pd-worst", String(res.worst_line), ""],
    ["joint stiffness", "pd-k", res.joint_stiffness_source, ""],
    ["wrench", "pd-wrench-src", res.wrench_source, ""],
  ];
  u$("pd-summary").querySelector("tbody").innerHTML = rows.map(([a, id, v, unit]) =>
    `<tr><th>${a}</th><td id="${id}">${v}</td><td>${unit}</td></tr>`).join("");
  const x = res.line;
  const data = [x];
  const series = [{ label: "line" }];
  const colours = ["#c0392b", "#2471a3", "#229954"];
  const bands = [];
  ["dx", "dy", "dz"].forEach((c, i) => {
    data.push(res.deflection_m_rad.map((d) => 1e3 * d[i]));
    series.push({ label: `${c} (mm)`, stroke: colours[i], width: 2 });
    if (band) {
      const k = data.length;
      data.push(res.hi95_m_rad.map((d) => 1e3 * d[i]), res.lo95_m_rad.map((d) => 1e3 * d[i]));
      series.push({ label: `${c} 95 % hi (mm)`, stroke: colours[i], dash: [4, 4], width: 1 },
                  { label: `${c} 95 % lo (mm)`, stroke: colours[i], dash: [4, 4], width: 1 });
      bands.push({ series: [k, k + 1], fill: colours[i] + "33" });
    }
  });
  const box = u$("pd-fig");
  if (use.pdPlot) use.pdPlot.destroy();
  box.innerHTML = "";
  use.pdPlot = new uPlot({ width: 760, height: 300, series, bands, legend: { live: true },
                           scales: { x: { time: false } },
                           axes: [{ label: "line of the path file" }, { label: "deflection (mm)", size: 60 }] }, data, box);
}

// ---- placement search (a queued job; progress from its events) -----------------------

// field of PlaceOptions, label, default, input kind (the command line's units: mm, deg)
const PLACE_FIELDS = [
  ["path", "Workpiece path CSV", "", "select"],
  ["robot", "Robot", "kr240-2", "select"],
  ["x_mm", "x range (mm)", "1400..1800", "text"], ["x_step_mm", "x step (mm)", "200", "number"],
  ["y_mm", "y range (mm)", "-200..200", "text"], ["y_step_mm", "y step (mm)", "200", "number"],
  ["z_mm", "z range (mm)", "200", "text"], ["z_step_mm", "z step (mm)", "100", "number"],
  ["yaw_deg", "yaw range (deg)", "0", "text"], ["yaw_step_deg", "yaw step (deg)", "15", "number"],
  ["tool_angle_step_deg", "tool angle step (deg)", "30", "number"],
  ["config", "configuration (any, or shoulder,elbow,wrist each 1 or -1)", "any", "text"],
  ["wrench", "process wrench fx,fy,fz (N), mx,my,mz (N m), tool frame (empty: the path's columns)", "", "text"],
  ["objective", "objective", "max", "objective"],
  ["workers", "worker processes (0: in the server's process; empty: a local Dask cluster)", "", "number"],
  ["out", "Output directory", "placement", "text"],
  ["force", "Replace its files", false, "checkbox"],
];

function buildPlaceForm() {
  const box = u$("pl-fields");
  for (const [field, label, value, kind] of PLACE_FIELDS) {
    const l = document.createElement("label");
    l.dataset.field = field; l.dataset.label = label;
    const id = `pl-${field}`;
    let input;
    if (kind === "select" || kind === "objective") {
      input = `<select id="${id}">${kind === "objective" ? ["max", "rms", "compliance"].map((o) => `<option>${o}</option>`).join("") : ""}</select>`;
    } else if (kind === "checkbox") {
      input = `<input type="checkbox" id="${id}">`;
    } else {
      input = `<input type="${kind === "number" ? "number" : "text"}" id="${id}" step="any">`;
    }
    l.innerHTML = `<span>${label}</span>${input}<small class="use-msg" data-for="${field}"></small>`;
    box.appendChild(l);
    const el = u$(id);
    if (kind !== "checkbox" && kind !== "select") el.value = String(value);
  }
}

function placeBody() {
  const b = {};
  for (const [field, , , kind] of PLACE_FIELDS) {
    const el = u$(`pl-${field}`);
    if (kind === "checkbox") b[field] = el.checked;
    else if (kind === "number") { if (el.value.trim() !== "") b[field] = Number(el.value); }
    else if (el.value.trim() !== "" || field === "path") b[field] = el.value.trim();
  }
  return b;
}

async function runPlace() {
  const view = u$("view-use");
  const form = u$("use-place");
  for (const m of form.querySelectorAll(".use-msg")) m.textContent = "";
  u$("pl-error").textContent = "";
  u$("pl-run").disabled = true;
  u$("pl-cancel").disabled = false;
  u$("pl-result").hidden = true;
  const bar = u$("pl-progress");
  bar.value = 0;
  // the job and fraction shown are this search's: a previous search's id would take a
  // Cancel clicked before this one's answer arrives (and cancel nothing)
  delete view.dataset.placeJob;
  delete view.dataset.placeFraction;
  delete view.dataset.placeCancel;
  view.dataset.place = "running";
  try {
    const res = await runJob("/api/jobs/place", placeBody(), (j) => {
      const first = !view.dataset.placeJob;
      view.dataset.placeJob = j.id;
      if (first && view.dataset.placeCancel) {  // Cancel was clicked before the job's id came
        cancelPlace().catch((e) => { u$("pl-error").textContent = String(e.message || e); });
      }
      if (j.fraction === null) bar.removeAttribute("value"); else bar.value = j.fraction;
      u$("pl-text").textContent = j.text === j.state ? j.text : `${j.state}: ${j.text}`;
      view.dataset.placeFraction = String(j.fraction);
    });
    showPlace(res);
    view.dataset.place = "done";
  } catch (err) {
    if (err.cancelled) {
      u$("pl-text").textContent = err.message;
      view.dataset.place = "cancelled";
    } else {
      showFieldError(form, err, u$("pl-error"));
      // the job's line is shown beside the form in its terms; not again with the CLI's options
      u$("pl-text").textContent = "failed";
      view.dataset.place = "error";
    }
  } finally {
    u$("pl-run").disabled = false;
    u$("pl-cancel").disabled = true;
  }
}

async function cancelPlace() {
  const view = u$("view-use");
  const id = view.dataset.placeJob;
  if (!id) { if (view.dataset.place === "running") view.dataset.placeCancel = "1"; return; }
  delete view.dataset.placeCancel;
  const r = await fetch(`/api/jobs/${encodeURIComponent(id)}`, { method: "DELETE", credentials: "same-origin",
                                                               headers: { [use.header]: use.csrf } });
  if (!r.ok) u$("pl-error").textContent = (await r.json().catch(() => ({}))).detail || String(r.status);
}

function showPlace(res) {
  u$("pl-result").hidden = false;
  const p = res.placement, unit = res.objective_unit;
  const rows = [
    ["x", "pl-best-x", fmt(p.x_mm, 7), "mm"], ["y", "pl-best-y", fmt(p.y_mm, 7), "mm"],
    ["z", "pl-best-z", fmt(p.z_mm, 7), "mm"], ["yaw", "pl-best-yaw", fmt(p.yaw_deg, 7), "deg"],
    [`objective: ${res.objective_name}`, "pl-best-objective", fmt(res.objective), unit],
    ["objective, nonlinear equilibrium with K_C", "pl-best-nonlinear", fmt(res.objective_nonlinear), unit],
    ["configuration (shoulder, elbow, wrist)", "pl-config",
     `${res.configuration.shoulder}, ${res.configuration.elbow}, ${res.configuration.wrist}`, ""],
    ["centre of the box", "pl-best-center", res.center_objective === null ? `infeasible: ${res.center_infeasible_reason}` : fmt(res.center_objective), res.center_objective === null ? "" : unit],
    ["better than the centre by", "pl-best-improvement", res.improvement_over_center === null ? "\u2014" : fmt(res.improvement_over_center, 4), "\u00d7"],
    ["placements searched", "pl-best-placements", String(res.search_space.placements), ""],
    ["infeasible placements", "pl-best-infeasible", String(res.infeasible.count), ""],
    ["evaluations", "pl-best-evaluations", String(res.search_space.evaluations), ""],
    ["run", "pl-best-where", `${res.run.where}, ${fmt(res.run.seconds, 3)} s`, ""],
  ];
  u$("pl-best").querySelector("tbody").innerHTML = rows.map(([a, id, v, un]) =>
    `<tr><th>${a}</th><td id="${id}">${v}</td><td>${un}</td></tr>`).join("") +
    res.warnings.map((w) => `<tr><td colspan="3" class="undefined">warning: ${optionsAsLabels(w, labelsOf(u$("use-place")))}</td></tr>`).join("");
  u$("pl-runners").querySelector("tbody").innerHTML = res.runner_ups.map((r, i) =>
    `<tr id="pl-runner-${i + 1}"><td>${i + 2}</td><td>${fmt(r.placement.x_mm, 7)}</td><td>${fmt(r.placement.y_mm, 7)}</td>` +
    `<td>${fmt(r.placement.z_mm, 7)}</td><td>${fmt(r.placement.yaw_deg, 7)}</td><td class="obj">${fmt(r.objective)} ${unit}</td></tr>`).join("");
  const files = u$("pl-files");
  files.innerHTML = "";
  const out = u$("pl-out").value.trim().replace(/\/+$/, "");
  for (const name of ["placement.json", "path_joints.csv", "objective_xy.png", "path_deflection.png"]) {
    files.appendChild(fileLink(`${out}/${name}`)); files.appendChild(document.createTextNode(" "));
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

// ---- export to a simulator (MJCF, URDF, SDF) --------------------------------------------

const EXPORT_SUFFIX = { mjcf: ".xml", urdf: ".urdf", sdf: ".sdf" };

function exportFormatChanged() {  // a name still ending in a format's suffix follows the format
  const out = u$("exp-out");
  const m = out.value.match(/^(.*)\.(xml|mjcf|urdf|sdf)$/);
  if (m) out.value = m[1] + EXPORT_SUFFIX[u$("exp-format").value];
}

async function runExport() {
  u$("exp-error").textContent = "";
  const view = u$("view-use");
  view.dataset.exp = "running";
  try {
    const res = await usePost("/api/jobs/export", {
      robot: u$("exp-robot").value, format: u$("exp-format").value, out: u$("exp-out").value,
      no_springs: u$("exp-nosprings").checked, force: u$("exp-force").checked });
    const k = res.stiffness_Nm_per_rad;
    u$("exp-wrote").textContent = `wrote ${res.file} (${res.format}) for ${res.robot}; ` +
      `joint stiffness: ${res.stiffness_source}` +
      (k ? ` [${k.map((v) => fmt(v / 1e3)).join(", ")}] kN m/rad` : "") +
      (res.report_id ? `; report ID ${res.report_id}` : "");
    for (const [id, items] of [["exp-left", res.left_out], ["exp-notes", res.notes]]) {
      u$(id).innerHTML = "";
      for (const item of items) {
        const li = document.createElement("li");
        li.textContent = item;
        u$(id).appendChild(li);
      }
    }
    u$("exp-result").hidden = false;
    view.dataset.exp = "done";
  } catch (err) {
    u$("exp-error").textContent = String(err.message || err);
    u$("exp-result").hidden = true;
    view.dataset.exp = "error";
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
  fillSelect(u$("pd-robot"), models, true);
  fillSelect(u$("exp-robot"), models, true);
  fillSelect(u$("pd-path"), f.paths.map((p) => [p, p]), true);
  fillSelect(u$("pl-path"), f.parts.map((p) => [p, p]), true);
  const firstPlace = !u$("pl-robot").options.length;
  fillSelect(u$("pl-robot"), robots, true);
  if (firstPlace && f.builtin.includes("kr240-2")) u$("pl-robot").value = "kr240-2";
  fillSelect(u$("cmp-a"), f.analyses.map((p) => [p, p]), true);
  fillSelect(u$("cmp-b"), f.analyses.map((p) => [p, p]), true);
  if (f.analyses.length > 1 && u$("cmp-a").value === u$("cmp-b").value) u$("cmp-b").value = f.analyses[1];
}

async function startUse() {
  const session = await useGet("/api/session");
  use.csrf = session.csrf_token; use.header = session.csrf_header;
  wrenchInputs(u$("use-wrench"), "use-w", [0, 0, -2000, 0, 200, 0]);
  wrenchInputs(u$("comp-wrench"), "comp-w", [500, 0, -1000, 0, 20, 0]);
  wrenchInputs(u$("pd-wrench"), "pd-w", [500, 0, -1000, 0, 20, 0]);
  buildPlaceForm();
  await refreshFiles();
  u$("use-robot").addEventListener("change", () => loadRobot().catch((e) => { u$("use-error").textContent = String(e.message || e); }));
  for (const [name] of WRENCH) u$(`use-w-${name}`).addEventListener("change", scheduleStiffness);
  u$("comp-run").addEventListener("click", runCompensation);
  u$("pd-run").addEventListener("click", runDeflection);
  u$("pl-run").addEventListener("click", runPlace);
  u$("pl-cancel").addEventListener("click", () => cancelPlace().catch((e) => { u$("pl-error").textContent = String(e.message || e); }));
  u$("use-pendant-mode").addEventListener("change", () => setConvention(u$("use-pendant-mode").checked));
  u$("cmp-run").addEventListener("click", runCompare);
  u$("exp-run").addEventListener("click", runExport);
  u$("exp-format").addEventListener("change", exportFormatChanged);
  u$("tab-use").addEventListener("click", () => refreshFiles().catch(() => {}));
  await loadRobot();
  u$("view-use").dataset.ready = "1";
}

// for the tests and the screenshot script: what the page shows, nothing to change it
window.useView = { poseDeg, wrench: () => wrenchOf("use-w"), state: use };
startUse().catch((err) => { u$("use-error").textContent = String(err.message || err); });
})();
