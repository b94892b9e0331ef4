// campaign gui: the page. Routes come from the server's OpenAPI document (/openapi.json);
// every POST carries the CSRF header given by /api/session.
"use strict";

const SLIDERS = [
  // key of the request, label, unit, max shown, step
  ["translation_sigma_um", "Tracker translation", "\u00b5m", 200, 1],
  ["rotation_sigma_urad", "Tracker rotation", "\u00b5rad", 500, 1],
  ["reflector_radius_mm", "Reflector triangle radius", "mm", 500, 5],
  ["force_sigma_N", "F/T force", "N", 100, 0.5],
  ["force_percent", "F/T force, of reading", "%", 5, 0.05],
  ["moment_sigma_Nm", "F/T moment", "N m", 20, 0.1],
  ["moment_percent", "F/T moment, of reading", "%", 5, 0.05],
  ["encoder_resolution_deg", "Encoder resolution", "deg", 0.01, 0.0001],
  // the robot beyond joint springs (0: off)
  ["link_compliance_percent", "Link compliance, of P's deflection", "%", 50, 0.5],
  ["lost_motion_mrad", "Lost motion per gear", "mrad", 2, 0.01],
  ["compensator_percent", "Axis-2 compensator, of k2", "%", 30, 0.5],
  ["n_tests", "Number of tests", "", 60, 1],
];

const state = { api: {}, csrf: null, header: null, inflight: false, dirty: false,
                timer: null, updates: 0, plots: {} };

function $(id) { return document.getElementById(id); }

async function getJSON(url) {
  const r = await fetch(url, { credentials: "same-origin" });
  if (!r.ok) throw new Error(`${url}: ${r.status}`);
  return r.json();
}

// A job's refusal in a form's terms (shared by the views): the API's refusal record carries
// `options` ({"--force": "force"}: each command-line option its line names -> the request
// field); a form labels its fields <label data-field="force" data-label="Replace its files">.
function fieldLabels(form) {
  const out = {};
  for (const el of form.querySelectorAll("[data-field][data-label]")) out[el.dataset.field] = el.dataset.label;
  return out;
}

// the line with each option it names replaced by the label of that field of the form
function inFormTerms(err, labels) {
  let text = String(err.detail || err.message || err);
  for (const [opt, field] of Object.entries(err.options || {})) {
    if (labels[field]) text = text.split(opt).join(`\u201c${labels[field]}\u201d`);
  }
  return text;
}

// The options a line names, each -> the request field of its name (--out -> out,
// --time-scale -> time_scale), for the views whose API answers carry no `options` record:
// with fieldLabels and inFormTerms, the line in the form's words.
function optionsNamed(text) {
  const out = {};
  for (const m of String(text).matchAll(/--[a-z][a-z0-9-]*/g)) {
    out[m[0]] = m[0].slice(2).replace(/-/g, "_");
  }
  return out;
}

function route(openapi, tag, method) {
  for (const [path, ops] of Object.entries(openapi.paths)) {
    const op = ops[method];
    if (op && (op.tags || []).includes(tag) && !path.includes("{")) {
      if (method === "get" && !path.endsWith("/defaults")) continue;
      return path;
    }
  }
  throw new Error(`the server has no ${method} route tagged ${tag}`);
}

// The choices of a request field (estimators, robust modes) as the API's OpenAPI document
// lists them (analysis/choices.py on the server; nothing typed here): {values, default}.
function apiChoices(openapi, schemaName, prop) {
  const schemas = openapi.components.schemas;
  const field = schemas[schemaName].properties[prop];
  const ref = (s) => (s && s.$ref ? schemas[s.$ref.split("/").pop()] : s);
  const own = ref(field) || {};
  const inner = own.enum ? own : ref((field.allOf || field.anyOf || []).find((s) => ref(s).enum)) || {};
  return { values: inner.enum || [], default: field.default ?? own.default };
}

// Fill <select> with the choices (labels: an optional note per value), the default selected.
function fillChoices(select, choices, notes = {}) {
  select.innerHTML = "";
  for (const v of choices.values) {
    const o = document.createElement("option");
    o.value = v; o.textContent = notes[v] ? `${v} (${notes[v]})` : v;
    select.appendChild(o);
  }
  if (choices.default !== undefined) select.value = choices.default;
}

// A job's refusal record ({detail, field, options, refused}) as an Error carrying them.
function jobError(err, status) {
  const detail = err && typeof err.detail === "string" ? err.detail : JSON.stringify(err && err.detail);
  const e = new Error(detail || String(status));
  e.detail = detail; e.field = (err && err.field) || null; e.options = (err && err.options) || {};
  e.refused = (err && err.refused) || [];
  e.problems = (err && err.problems) || undefined;
  e.status = status;
  return e;
}

// A queued job of /api/jobs (202), shared by the views: post(url, body) -> [status, doc] is
// the view's own POST (its CSRF header); followed by the job's server-sent events to its end,
// onProgress(job) at each change, started(id) once queued. Resolves with its result;
// rejects with its error (an Error from jobError, or .cancelled).
async function followJob(post, url, body, onProgress, started) {
  const [status, doc] = await post(url, body);
  if (status >= 400) throw jobError(doc, status);
  if (status !== 202) return doc;
  if (started) started(doc.id);
  if (onProgress) onProgress(doc);
  const ended = (j) => {
    if (j.state === "done") return { ok: j.result };
    if (j.state === "failed") return { err: jobError(j.error, j.error.status) };
    if (j.state === "cancelled") {
      const e = new Error(j.text); e.cancelled = true; return { err: e };
    }
    return null;
  };
  const end = await new Promise((resolve) => {
    const es = new EventSource(`/api/jobs/${encodeURIComponent(doc.id)}/events`);
    es.onmessage = (ev) => {
      const j = JSON.parse(ev.data);
      if (onProgress) onProgress(j);
      const e = ended(j);
      if (e) { es.close(); resolve(e); }
    };
    es.onerror = async () => {  // the stream broke: ask for the state until it ends
      es.close();
      for (;;) {
        const j = await getJSON(`/api/jobs/${encodeURIComponent(doc.id)}`).catch(() => null);
        if (j) { if (onProgress) onProgress(j); const e = ended(j); if (e) { resolve(e); return; } }
        await new Promise((t) => setTimeout(t, 300));
      }
    };
  });
  if (end.err) throw end.err;
  return end.ok;
}

const METHOD_NOTES = { ols: "the paper's", exact: "nonlinear" };

function buildSliders(schema, defaults) {
  const box = $("sliders");
  for (const [key, label, unit, max, step] of SLIDERS) {
    // an optional field's bounds are in its anyOf (number | null)
    const field = schema.properties[key] || {};
    const prop = (field.anyOf || [field]).find((s) => s.type === "number" || s.type === "integer") || {};
    const hi = Math.min(max, prop.maximum ?? max);
    const lo = prop.minimum ?? (key === "n_tests" ? 1 : 0);
    const start = key === "n_tests" ? 10 : Math.min(hi, defaults[key]);
    const row = document.createElement("label");
    row.className = "slider";
    row.innerHTML = `<span>${label}${unit ? " (" + unit + ")" : ""}</span>` +
      `<input type="range" id="s-${key}" name="${key}" min="${lo}" max="${hi}" step="${step}">` +
      `<output id="v-${key}"></output>`;
    box.appendChild(row);
    const input = row.querySelector("input");
    input.value = String(start);
    const show = () => { $(`v-${key}`).textContent = Number(input.value).toPrecision(4).replace(/\.?0+$/, ""); };
    show();
    input.addEventListener("input", () => { show(); schedule(); });
  }
}

function numbers(text, where) {
  const v = text.split(",").map((s) => s.trim()).filter((s) => s !== "").map(Number);
  if (v.some((x) => !Number.isFinite(x))) throw new Error(`${where}: not a list of numbers`);
  return v;
}

function body() {
  const b = { robot: $("robot").value.trim(), poses: $("poses").value,
              method: $("method").value, model: $("sens-model").value,
              trials: Number($("trials").value) };
  for (const [key] of SLIDERS) b[key] = Number($(`s-${key}`).value);
  // rotation: its own sigma, or the fit of the reflector triangle (one of the two sliders)
  if ($("rotation-from").value === "reflectors") delete b.rotation_sigma_urad;
  else delete b.reflector_radius_mm;
  const w = $("wrench").value.trim();
  if (w) b.wrench_N_Nm = numbers(w, "wrench");
  const k = $("joint_k").value.trim();
  if (k) b.joint_stiffness_Nm_per_rad = numbers(k, "joint stiffness");
  if (b.poses === "plan") b.plan = $("plan").value.trim();
  if (b.poses === "typed") {
    b.q_deg = $("q_deg").value.split("\n").filter((l) => l.trim()).map((l) => numbers(l, "q"));
  }
  return b;
}

function schedule() {
  clearTimeout(state.timer);
  state.timer = setTimeout(update, 15);
}

async function update() {
  // one request in flight at most: moves made meanwhile are sent, coalesced, when it
  // returns (aborting a fetch would not stop the server's work)
  if (state.inflight) { state.dirty = true; return; }
  let payload;
  try { payload = body(); } catch (err) { $("sens-error").textContent = err.message; return; }
  state.inflight = true;
  const t0 = performance.now();
  try {
    const r = await fetch(state.api.sensitivity, {
      method: "POST", credentials: "same-origin",
      headers: { "Content-Type": "application/json", [state.header]: state.csrf },
      body: JSON.stringify(payload) });
    const data = await r.json();
    if (!r.ok) {
      $("sens-error").textContent = data.detail || r.statusText;
      // the figures, the table and the timing were the previous settings': not shown
      $("sens-status").textContent = "";
      $("sens-note").textContent = "";
      $("sens-figures").hidden = true;
      $("sens-table").hidden = true;
      document.body.dataset.shown = "error:" + JSON.stringify(payload);
    } else {
      $("sens-error").textContent = "";
      $("sens-figures").hidden = false;
      $("sens-table").hidden = false;
      render(data);
      state.updates += 1;
      document.body.dataset.updates = String(state.updates);
      document.body.dataset.shown = JSON.stringify(payload);  // the settings on display
      $("sens-status").textContent = `${data.trials} trials of ${data.n_tests} tests ` +
        `(${data.method}) in ${Math.round(performance.now() - t0)} ms`;
      // ols/wls: the linearisation bias each trial is corrected for, as Analyze does
      $("sens-note").textContent = data.note || "";
    }
  } catch (err) {
    $("sens-error").textContent = String(err);
  } finally {
    state.inflight = false;
    if (state.dirty) { state.dirty = false; update(); }
  }
}

function fmt(v) { return v === null || v === undefined ? "\u2013" : Math.round(v).toString(); }

function render(d) {
  const tb = document.querySelector("#sens-table tbody");
  tb.innerHTML = "";
  for (const j of d.joints) {
    const tr = document.createElement("tr");
    tr.id = `row-k${j.joint}`;
    const iqr = j.q75_Nm_per_rad === null ? null : j.q75_Nm_per_rad - j.q25_Nm_per_rad;
    const cells = [`k${j.joint}`, fmt(j.k_true_Nm_per_rad), fmt(j.median_Nm_per_rad), fmt(iqr),
                   fmt(j.std_Nm_per_rad), j.predicted_se_Nm_per_rad === null ?
                   "not identifiable" : fmt(j.predicted_se_Nm_per_rad), String(j.rejected)];
    const names = ["joint", "k-true", "median", "iqr", "std", "predicted-se", "rejected"];
    cells.forEach((c, i) => {
      const td = document.createElement("td");
      td.className = names[i];
      td.textContent = c;
      tr.appendChild(td);
    });
    tb.appendChild(tr);
  }
  plotSets(d);
  plotSpread(d);
  plotCurve(d);
}

function rel(v, k) { return v === null ? null : 100 * (v / k - 1); }

// a figure no wider than the window (a phone: 390 px) less the page's margins
function fitted(width) {
  return Math.max(240, Math.min(width, document.documentElement.clientWidth - 60));
}

function plot(id, opts, data) {
  opts = { ...opts, width: fitted(opts.width) };
  const old = state.plots[id];
  if (old && old.series.length === opts.series.length) { old.setData(data); return; }
  if (old) old.destroy();
  state.plots[id] = new uPlot(opts, data, $(id));
}

const AXES_X = { label: "joint", values: (u, v) => v.map((x) => Number.isInteger(x) ? `k${x}` : "") };

function plotSets(d) {
  const x = d.joints.map((j) => j.joint);
  const kt = d.joints.map((j) => j.k_true_Nm_per_rad);
  const data = [x, d.joints.map((j, i) => rel(j.median_Nm_per_rad, kt[i])),
                d.joints.map((j, i) => rel(j.q25_Nm_per_rad, kt[i])),
                d.joints.map((j, i) => rel(j.q75_Nm_per_rad, kt[i]))];
  const series = [{ label: "joint" },
    { label: "median", stroke: "#24344d", width: 2.5 },
    { label: "quartile 1", stroke: "#24344d", dash: [2, 3] },
    { label: "quartile 3", stroke: "#24344d", dash: [2, 3] }];
  const colors = ["#d95f02", "#1b9e77", "#7570b3", "#e7298a", "#66a61e"];
  d.sets_Nm_per_rad.forEach((s, n) => {
    data.push(s.map((v, i) => rel(v, kt[i])));
    series.push({ label: `trial ${n + 1}`, stroke: colors[n % colors.length], dash: [8, 4], width: 1.2 });
  });
  plot("fig-sets", { width: 560, height: 320, scales: { x: { time: false } }, series,
                     axes: [AXES_X, { label: "k identified / k true - 1 (%)", size: 60 }] }, data);
}

function plotSpread(d) {
  const x = d.joints.map((j) => j.joint);
  const pc = (v, j) => (v === null ? null : 100 * v / j.k_true_Nm_per_rad);
  const data = [x, d.joints.map((j) => pc(j.std_Nm_per_rad, j)),
                d.joints.map((j) => j.q75_Nm_per_rad === null ? null :
                  pc((j.q75_Nm_per_rad - j.q25_Nm_per_rad) / 1.349, j)),
                d.joints.map((j) => pc(j.predicted_se_Nm_per_rad, j))];
  const series = [{ label: "joint" },
    { label: "Monte-Carlo std", stroke: "#d95f02", width: 2, points: { size: 8 } },
    { label: "IQR / 1.349", stroke: "#7570b3", width: 2, points: { size: 8 } },
    { label: "planner's predicted se", stroke: "#1b9e77", width: 2, dash: [6, 3], points: { size: 8 } }];
  plot("fig-spread", { width: 560, height: 320, scales: { x: { time: false } }, series,
                       axes: [AXES_X, { label: "relative spread of k (%)", size: 60 }] }, data);
}

const JOINT_COLORS = ["#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#a6761d"];

function plotCurve(d) {
  const x = d.curve_tests;
  const data = [x];
  const series = [{ label: "tests" }];
  d.joints.forEach((j, c) => {
    data.push(d.curve_relative_se.map((row) => row[c] === null ? null : 100 * row[c]));
    series.push({ label: `k${j.joint} predicted`, stroke: JOINT_COLORS[c], width: 1.5 });
  });
  d.joints.forEach((j, c) => {
    const std = j.std_Nm_per_rad === null ? null : 100 * j.std_Nm_per_rad / j.k_true_Nm_per_rad;
    data.push(x.map((n) => (n === d.n_tests ? std : null)));
    series.push({ label: `k${j.joint} Monte-Carlo`, stroke: JOINT_COLORS[c], width: 0,
                  points: { show: true, size: 9, fill: JOINT_COLORS[c] } });
  });
  plot("fig-curve", { width: 1140, height: 300, scales: { x: { time: false }, y: { distr: 3 } },
                      series, legend: { live: true },
                      axes: [{ label: "number of tests" },
                             { label: "relative se of k (%), log scale", size: 70 }] }, data);
}

function showView(name) {
  for (const b of document.querySelectorAll(".tab")) b.classList.toggle("active", b.dataset.view === name);
  for (const v of document.querySelectorAll(".view")) v.hidden = v.id !== `view-${name}`;
}

function rotationChanged() {
  const fromReflectors = $("rotation-from").value === "reflectors";
  $("s-rotation_sigma_urad").disabled = fromReflectors;
  $("s-reflector_radius_mm").disabled = !fromReflectors;
}

function posesChanged() {
  const p = $("poses").value;
  for (const el of document.querySelectorAll(".for-plan")) el.hidden = p !== "plan";
  for (const el of document.querySelectorAll(".for-typed")) el.hidden = p !== "typed";
}

async function start() {
  const [session, openapi] = await Promise.all([getJSON("/api/session"), getJSON("/openapi.json")]);
  state.csrf = session.csrf_token;
  state.header = session.csrf_header;
  $("workspace").textContent = `workspace: ${session.workspace}`;
  if (!session.hardware) {
    // started without --hardware: the server refuses a run on hardware, so the page offers none
    $("acq-fake").checked = true;
    $("acq-fake").disabled = true;
    $("acq-fake").title = "this GUI was started without --hardware: simulated lab only";
    $("acq-confirm-row").hidden = true;
    $("acq-hardware-note").hidden = false;
  }
  state.api.sensitivity = route(openapi, "sensitivity", "post");
  const defaults = await getJSON(route(openapi, "sensitivity", "get"));
  robotFillDatalist($("robots"), await robotChoices());
  $("urdf-upload").addEventListener("click", () => robotUpload($("urdf-file"), $("urdf-tip"),
    $("urdf-msg"), async (value) => {
      robotFillDatalist($("robots"), await robotChoices());
      $("robot").value = value;
      schedule();
    }).catch((err) => { $("urdf-msg").textContent = String(err); }));
  buildSliders(openapi.components.schemas.SensitivityRequest, defaults);
  fillChoices($("method"), apiChoices(openapi, "SensitivityRequest", "method"), METHOD_NOTES);
  fillChoices($("sens-model"), apiChoices(openapi, "SensitivityRequest", "model"));
  for (const id of ["robot", "joint_k", "poses", "plan", "q_deg", "wrench", "method",
                    "sens-model", "trials"]) {
    $(id).addEventListener("change", schedule);
  }
  $("poses").addEventListener("change", posesChanged);
  posesChanged();
  $("rotation-from").addEventListener("change", () => { rotationChanged(); schedule(); });
  rotationChanged();
  update();
}

// The tabs work as soon as the page is there, not once the server has answered start()'s
// requests (a click made meanwhile was lost).
for (const b of document.querySelectorAll(".tab")) b.addEventListener("click", () => showView(b.dataset.view));

// Forms are driven by script: Enter in a field never submits (reloads) the page. Attached
// here, not inline: the page's Content Security Policy (script-src 'self') blocks inline handlers.
for (const f of document.querySelectorAll("form")) f.addEventListener("submit", (e) => e.preventDefault());
// Enter in a text or number field of a form runs the form's action (its data-enter button),
// as a submit button would (the forms have none: their buttons run scripts).
for (const f of document.querySelectorAll("form[data-enter]")) {
  f.addEventListener("keydown", (e) => {
    const t = e.target;
    if (e.key !== "Enter" || e.isComposing || t.tagName !== "INPUT" ||
        ["checkbox", "radio", "button", "file", "range"].includes(t.type)) return;
    const button = document.getElementById(f.dataset.enter);
    if (!button || button.disabled) return;
    e.preventDefault();
    button.click();
  });
}

start().catch((err) => { $("sens-error").textContent = String(err); });
