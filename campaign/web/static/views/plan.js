// campaign gui: the Plan and Analyze views (their own file; app.js is untouched).
// POSTs carry the CSRF header of /api/session.
"use strict";

const pv = { csrf: null, header: null, fields: [], last: null, plots: {} };

function pvEl(id) { return document.getElementById(id); }

async function pvPost(url, body) {
  const r = await fetch(url, { method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", [pv.header]: pv.csrf },
    body: JSON.stringify(body) });
  return [r.ok, await r.json()];
}

// a POST as app.js's followJob wants it: [status, document]
async function pvPostStatus(url, body) {
  const r = await fetch(url, { method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", [pv.header]: pv.csrf },
    body: JSON.stringify(body) });
  return [r.status, await r.json().catch(() => ({ detail: `${r.status}` }))];
}

// a number with `digits` decimals; a value that rounds to zero is "0.0", never "-0.0"
function pvText(v, digits) {
  if (v === null || v === undefined) return "\u2013";
  const t = v.toFixed(digits);
  return /^-0\.?0*$/.test(t) ? t.slice(1) : t;
}

// ---- Plan ----
// The form is generated from /api/plan/form: every key of the protocol schema, keyed by
// the paths the command line's messages use (load_cases[1].force_N). Rows of
// [[load_cases]] and [[zones]] and the [instruments.ROLE] tables are added and removed
// here; every value travels as the text typed and the server writes the TOML.
const ROW_SECTIONS = { load_cases: "load case", zones: "zone" };
const ROLE_SECTIONS = { instruments: "instrument" };

function pvId(key) { return "pf-" + key.replace(/[^A-Za-z0-9_]+/g, "-").replace(/-+$/, ""); }

function pvCollect() {
  const values = {};
  for (const input of document.querySelectorAll("#plan-fields [data-key]:is(input, select, textarea)")) {
    values[input.dataset.key] = input.value;
  }
  return values;
}

function pvRows(values, name) {
  const ids = new Set();
  const re = new RegExp(`^${name}\\[(\\d+)\\]`);
  for (const k of Object.keys(values)) { const m = k.match(re); if (m) ids.add(Number(m[1])); }
  return [...ids].sort((a, b) => a - b);
}

function pvRoles(values, name) {
  const out = [];
  for (const k of Object.keys(values)) {
    if (k.startsWith(name + ".")) { const r = k.split(".")[1]; if (!out.includes(r)) out.push(r); }
  }
  return out;
}

function pvInput(f, key, value) {
  let input;
  if (f.kind === "choice" || f.kind === "bool") {
    input = document.createElement("select");
    const opts = f.required && f.kind === "choice" ? f.choices : ["", ...f.choices];
    for (const c of opts) {
      const o = document.createElement("option");
      o.value = c; o.textContent = c === "" ? `(default${f.default ? ": " + f.default : ""})` : c;
      input.appendChild(o);
    }
    if (value && !opts.includes(value)) {  // a value the reader will refuse: kept, shown
      const o = document.createElement("option"); o.value = value; o.textContent = value;
      input.appendChild(o);
    }
  } else {
    input = document.createElement("input");
    if (f.suggestions.length) input.setAttribute("list", `pv-list-${f.key.replace(/\W+/g, "-")}`);
    if (f.kind === "date") input.placeholder = "YYYY-MM-DD";
    else if (f.kind === "vector") input.placeholder = f.default || `${f.size} numbers, comma-separated`;
    else if (f.kind === "table") input.placeholder = f.default && f.default !== "{}" ? f.default : "{ name = value, ... }";
    else input.placeholder = f.default;
  }
  input.id = pvId(key);
  input.dataset.key = key;
  input.value = value ?? "";
  return input;
}

function pvFieldRow(f, key, value) {
  const row = document.createElement("label");
  row.className = "pv-field";
  row.dataset.key = key;
  const leaf = key.replace(/^.*?\]\./, "").replace(/^instruments\.[^.]+\./, "");
  const span = document.createElement("span");
  span.textContent = `${leaf}${f.unit ? " (" + f.unit + ")" : ""}${f.required ? " *" : ""}`;
  span.title = `${key}: ${f.kind}${f.size ? " of " + f.size : ""}. ${f.help}`;
  row.appendChild(span);
  const input = pvInput(f, key, value);
  row.appendChild(input);
  row.appendChild(pvMsg());
  // "keys with a value only" hides the empty optional fields (the reader's defaults)
  const mark = () => row.classList.toggle("pv-empty", !f.required && input.value.trim() === "");
  input.addEventListener("input", mark);
  input.addEventListener("change", mark);
  mark();
  return row;
}

function pvMsg() {
  const msg = document.createElement("small");
  msg.className = "pv-msg"; msg.setAttribute("role", "alert");
  return msg;
}

function pvButton(text, cls, onClick) {
  const b = document.createElement("button");
  b.type = "button"; b.textContent = text; b.className = cls;
  b.addEventListener("click", onClick);
  return b;
}

function planRender(values) {
  const box = pvEl("plan-fields");
  box.innerHTML = "";
  const lists = document.createDocumentFragment();
  for (const f of pv.fields) {
    if (!f.suggestions.length) continue;
    const dl = document.createElement("datalist");
    dl.id = `pv-list-${f.key.replace(/\W+/g, "-")}`;
    for (const s of f.suggestions) { const o = document.createElement("option"); o.value = s; dl.appendChild(o); }
    lists.appendChild(dl);
  }
  box.appendChild(lists);
  const sections = [];
  for (const f of pv.fields) if (!sections.includes(f.section)) sections.push(f.section);
  for (const section of sections) {
    const fields = pv.fields.filter((f) => f.section === section);
    const fs = document.createElement("fieldset");
    fs.className = "pv-section"; fs.id = `pv-sec-${section}`;
    const legend = document.createElement("legend");
    legend.textContent = section in ROW_SECTIONS ? `[[${section}]]` :
      section in ROLE_SECTIONS ? `[${section}.ROLE]` : `[${section}]`;
    legend.title = fields[0].help;
    fs.appendChild(legend);
    if (section in ROW_SECTIONS) {
      pvRows(values, section).forEach((id, i) => {
        const block = document.createElement("div");
        block.className = "pv-block"; block.dataset.row = String(i);
        block.dataset.key = `${section}[${i}]`;
        const h = document.createElement("h4"); h.textContent = `${ROW_SECTIONS[section]} ${i + 1} (${section}[${i}])`;
        block.appendChild(h);
        block.appendChild(pvMsg());
        for (const f of fields) {
          const key = f.key.replace("[*]", `[${i}]`);
          block.appendChild(pvFieldRow(f, key, values[f.key.replace("[*]", `[${id}]`)]));
        }
        block.appendChild(pvButton(`remove ${ROW_SECTIONS[section]} ${i + 1}`, "pv-remove",
          () => planEdit((v) => pvRemoveRow(v, section, i))));
        fs.appendChild(block);
      });
      fs.appendChild(pvButton(`add a ${ROW_SECTIONS[section]}`, "pv-add",
        () => planEdit((v) => pvAddRow(v, section, fields))));
    } else if (section in ROLE_SECTIONS) {
      for (const role of pvRoles(values, section)) {
        const block = document.createElement("div");
        block.className = "pv-block"; block.dataset.role = role;
        block.dataset.key = `${section}.${role}`;
        const h = document.createElement("h4"); h.textContent = `${section}.${role}`;
        block.appendChild(h);
        block.appendChild(pvMsg());
        for (const f of fields) {
          const key = f.key.replace(".*.", `.${role}.`);
          block.appendChild(pvFieldRow(f, key, values[key]));
        }
        block.appendChild(pvButton(`remove ${role}`, "pv-remove", () => planEdit((v) => {
          for (const k of Object.keys(v)) if (k.startsWith(`${section}.${role}.`)) delete v[k];
        })));
        fs.appendChild(block);
      }
      const add = document.createElement("label");
      add.className = "pv-add-role";
      add.innerHTML = `<span>new ${ROLE_SECTIONS[section]} role</span>`;
      const name = document.createElement("input");
      name.id = `pv-new-${section}`; name.placeholder = "e.g. pose, robot, force_torque, load";
      add.appendChild(name);
      add.appendChild(pvButton(`add an ${ROLE_SECTIONS[section]}`, "pv-add", () => planEdit((v) => {
        const role = name.value.trim();
        if (role) for (const f of fields) v[f.key.replace(".*.", `.${role}.`)] = "";
      })));
      fs.appendChild(add);
    } else {
      for (const f of fields) fs.appendChild(pvFieldRow(f, f.key, values[f.key]));
    }
    box.appendChild(fs);
  }
}

function planEdit(change) {
  const values = pvCollect();
  change(values);
  planRender(values);
}

function pvRemoveRow(values, section, index) {
  const re = new RegExp(`^${section}\\[(\\d+)\\]`);
  const ids = pvRows(values, section);
  const out = {};
  for (const [k, v] of Object.entries(values)) {
    const m = k.match(re);
    if (!m) { out[k] = v; continue; }
    const pos = ids.indexOf(Number(m[1]));
    if (pos === index) continue;
    out[k.replace(re, `${section}[${pos > index ? pos - 1 : pos}]`)] = v;
  }
  for (const k of Object.keys(values)) delete values[k];
  Object.assign(values, out);
}

function pvAddRow(values, section, fields) {
  const n = pvRows(values, section).length;
  for (const f of fields) values[f.key.replace("[*]", `[${n}]`)] = "";
}

async function planLoadForm() {
  const src = pvEl("plan-source").value;
  const r = await fetch(`/api/plan/form?source=${encodeURIComponent(src)}`, { credentials: "same-origin" });
  const d = await r.json();
  pvEl("plan-error").textContent = "";
  if (!r.ok) { pvEl("plan-error").textContent = d.detail; return; }
  pv.fields = d.fields;
  planRender(d.values);
}

function planBody() {
  const values = {};
  for (const [k, v] of Object.entries(pvCollect())) if (v.trim() !== "") values[k] = v;
  return { source: pvEl("plan-source").value, values, complete: true,
           name: pvEl("plan-name").value.trim(), strategy: pvEl("plan-strategy").value,
           seed: Number(pvEl("plan-seed").value), candidates: Number(pvEl("plan-candidates").value),
           force: pvEl("plan-force").checked };
}

function planClearMessages() {
  pvEl("plan-error").textContent = "";
  for (const m of document.querySelectorAll("#view-plan .pv-msg")) m.textContent = "";
  for (const m of document.querySelectorAll("#view-plan .pv-bad")) m.classList.remove("pv-bad");
}

// the previous plan's results emptied: a new "Save and plan" shows its own, or its refusal
function planClearResults() {
  pv.last = null;
  for (const id of Object.keys(pv.plots)) { pv.plots[id].destroy(); delete pv.plots[id]; }
  for (const sel of ["#plan-se tbody", "#plan-rows tbody"]) document.querySelector(sel).innerHTML = "";
  for (const id of ["plan-map-hover", "plan-map-caption"]) pvEl(id).textContent = "";
  pvEl("plan-map-png").hidden = true;
}

async function planRun(saveOnly) {
  planClearMessages();
  if (!saveOnly) planClearResults();
  pvEl("plan-status").textContent = saveOnly ? "saving\u2026" : "planning\u2026";
  document.body.dataset.plan = "running";
  // "Save and plan" is a queued job (/api/plan/run answers 202): followed to its end
  let ok = true, d;
  if (saveOnly) [ok, d] = await pvPost("/api/plan/save", planBody());
  else {
    try {
      d = await followJob(pvPostStatus, "/api/plan/run", planBody(),
        (j) => { if (j.text) pvEl("plan-status").textContent = j.text; });
    } catch (err) {
      ok = false;
      d = { detail: err.detail || String(err), field: err.field, options: err.options,
            problems: err.problems };
    }
  }
  if (!ok) {
    const rest = [];
    for (const p of d.problems || [{ field: d.field, detail: d.detail }]) {
      const row = p.field && document.querySelector(`#view-plan :is(label, div)[data-key="${CSS.escape(p.field)}"]`);
      const msg = row && row.querySelector(":scope > .pv-msg");
      const text = inFormTerms({ detail: p.detail, options: d.options }, fieldLabels(pvEl("plan-form")));
      if (msg) {
        msg.textContent = msg.textContent ? `${msg.textContent}\n${text}` : text;
        row.classList.add("pv-bad");
      } else rest.push(text);
    }
    pvEl("plan-error").textContent = rest.join("\n") ||
      (d.detail && !d.problems ? inFormTerms(d, fieldLabels(pvEl("plan-form"))) : "");
    const first = document.querySelector("#view-plan .pv-bad");
    if (first) first.scrollIntoView({ block: "center" });
    pvEl("plan-status").textContent = "";
    document.body.dataset.plan = "error";
    return;
  }
  pvAddSource(d.protocol);
  if (saveOnly) {
    pvEl("plan-status").textContent = `saved ${d.protocol}; the protocol reader accepts it`;
    document.body.dataset.plan = "saved";
    return;
  }
  planShow(d);
  document.body.dataset.plan = "done";
}

function planShow(d) {
  const s = d.summary;
  pv.last = d;
  pvEl("acq-plan").value = d.out;  // the plan just written is the one to acquire next
  pvEl("plan-status").textContent = `${s.tests} tests at ${s.poses} poses of ${s.robot} ` +
    `(${s.strategy}, ${s.candidates.poses_passing} of ${s.candidates.drawn} candidates pass); ` +
    `saved ${d.protocol} and ${d.out}/`;
  pvEl("plan-error").textContent = (d.warnings || []).map((w) => `warning: ${w}`).join("\n");
  const tb = document.querySelector("#plan-se tbody");
  tb.innerHTML = "";
  for (const j of s.predicted_standard_errors) {
    const tr = document.createElement("tr");
    tr.id = `plan-se-k${j.joint}`;
    const cells = [["joint", `k${j.joint}`], ["prior", pvText(j.k_prior_N_m_per_rad / 1e3, 1)],
      ["se", pvText(j.se_design_N_m_per_rad / 1e3, 3)], ["se-pct", pvText(j.se_design_percent, 3)],
      ["se-random-pct", pvText(j.se_random_percent, 3)]];
    for (const [c, t] of cells) {
      const td = document.createElement("td"); td.className = c; td.textContent = t; tr.appendChild(td);
    }
    tb.appendChild(tr);
  }
  const pb = document.querySelector("#plan-rows tbody");
  pb.innerHTML = "";
  for (const r of d.rows) {
    const tr = document.createElement("tr");
    tr.className = "plan-row";
    const q = [1, 2, 3, 4, 5, 6].map((i) => pvText(r[`q${i}_model_deg`], 3)).join(", ");
    for (const t of [r.test, r.pose, r.zone, r.load_case, q, pvText(r.inv_kappa_F, 4)]) {
      const td = document.createElement("td"); td.textContent = String(t); tr.appendChild(td);
    }
    pb.appendChild(tr);
  }
  planPlotSe(s);
  if (d.map) planPlotMap(d.map);
  const map = d.files.find((f) => f.endsWith("plan_map.png"));
  const link = pvEl("plan-map-png");
  if (map) { link.href = `/api/runs/file?path=${encodeURIComponent(map)}`; link.hidden = false; }
  else link.hidden = true;
}

function pvPlot(id, opts, data) {
  if (pv.plots[id]) pv.plots[id].destroy();
  pv.plots[id] = new uPlot(opts, data, pvEl(id));
  return pv.plots[id];
}

function planPlotSe(s) {
  const rows = s.predicted_standard_errors;
  const target = Number(pvEl("plan-target").value);
  const x = rows.map((j) => j.joint);
  const bars = uPlot.paths.bars({ size: [0.35, 40], align: 0 });
  const data = [x, rows.map((j) => j.se_design_percent), rows.map((j) => j.se_random_percent),
                x.map(() => (Number.isFinite(target) && target > 0 ? target : null))];
  pvPlot("plan-se-fig", {
    width: 620, height: 300, scales: { x: { time: false, range: [0.4, x.length + 0.6] }, y: { range: (u, lo, hi) => [0, Math.max(hi, target || 0) * 1.15] } },
    series: [{ label: "joint", value: (u, v) => (v === null ? "\u2013" : `k${v}`) },
      { label: "predicted se, chosen design (% of k)", stroke: "#1b9e77", fill: "#1b9e7799", paths: bars, points: { show: false },
        value: (u, v) => (v === null ? "\u2013" : v.toFixed(3) + " %") },
      { label: "random zone design (% of k)", stroke: "#d95f02", width: 0, points: { show: true, size: 9, fill: "#d95f02" },
        value: (u, v) => (v === null ? "\u2013" : v.toFixed(3) + " %") },
      { label: "target (% of k)", stroke: "#b00020", dash: [6, 4], width: 1.5, points: { show: false },
        value: (u, v) => (v === null ? "\u2013" : v + " %") }],
    axes: [{ label: "joint", values: (u, v) => v.map((t) => (Number.isInteger(t) ? `k${t}` : "")) },
           { label: "predicted se of k (% of prior k)", size: 60 }],
  }, data);
}

const MAP_KINDS = ["", "candidate passing the thresholds", "candidate rejected",
  "random zone design", "chosen pose"];

function planMapHover(u, pts, m) {
  // the point nearest the cursor on screen, whatever its series (hidden series skipped)
  const out = pvEl("plan-map-hover");
  const { left, top } = u.cursor;
  if (left === undefined || left < 0) { out.textContent = ""; return; }
  // nearest per kind; a chosen (then random) pose under the cursor wins over the
  // candidate drawn at the same place (every pose of a design is a candidate)
  const near = [null, null, null, null, null], dist = [225, 225, 225, 225, 225];
  for (const p of pts) {
    if (!u.series[p[1]].show) continue;
    const dx = u.valToPos(p[0], "x") - left, dy = u.valToPos(p[2], "y") - top;
    const d = dx * dx + dy * dy;
    if (d < dist[p[1]]) { dist[p[1]] = d; near[p[1]] = p; }
  }
  let best = [4, 3].map((k) => (dist[k] <= 36 ? near[k] : null)).find((p) => p);
  if (!best) {
    const k = [1, 2, 3, 4].filter((i) => near[i]).sort((a, b) => dist[a] - dist[b])[0];
    best = k === undefined ? null : near[k];
  }
  if (!best) { out.textContent = ""; return; }
  const what = best[1] === 4 ? `chosen pose ${best[3] + 1}, tests ${m.chosen.tests[best[3]].join(", ")}`
    : MAP_KINDS[best[1]];
  out.textContent = `${what}: \u03b8\u2082 = ${best[0].toFixed(3)} deg, ` +
    `\u03b8\u2083 = ${best[2].toFixed(3)} deg (model convention)`;
}

function planPlotMap(m) {
  // one x array for every series (uPlot's aligned data): candidates, chosen, random
  // poses sorted by theta_2, each series null where the point is another series'
  const pts = [];
  m.candidates.q2_deg.forEach((x, i) => pts.push([x, m.candidates.passing[i] ? 1 : 2, m.candidates.q3_deg[i], i]));
  m.random.q2_deg.forEach((x, i) => pts.push([x, 3, m.random.q3_deg[i], i]));
  m.chosen.q2_deg.forEach((x, i) => pts.push([x, 4, m.chosen.q3_deg[i], i]));
  pts.sort((a, b) => a[0] - b[0]);
  const data = [pts.map((p) => p[0]), [], [], [], []];
  const tests = [];
  for (const p of pts) {
    for (let s = 1; s <= 4; s++) data[s].push(p[1] === s ? p[2] : null);
    tests.push(p[1] === 4 ? m.chosen.tests[p[3]] : null);
  }
  const g = m.grid;
  const lo2 = g.theta2_deg[0], hi2 = g.theta2_deg[g.theta2_deg.length - 1];
  const lo3 = g.theta3_deg[0], hi3 = g.theta3_deg[g.theta3_deg.length - 1];
  const fmt = (v) => (v === null || v === undefined ? "\u2013" : v.toFixed(2) + " deg");
  const flat = g.inv_kappa.flat();
  const kmin = Math.min(...flat), kmax = Math.max(...flat);
  const drawGrid = (u) => {
    const ctx = u.ctx;
    const n2 = g.theta2_deg.length, n3 = g.theta3_deg.length;
    const d2 = (hi2 - lo2) / (n2 - 1), d3 = (hi3 - lo3) / (n3 - 1);
    ctx.save();
    for (let i3 = 0; i3 < n3; i3++) {
      for (let i2 = 0; i2 < n2; i2++) {
        const v = g.inv_kappa[i3][i2];
        const x0 = u.valToPos(g.theta2_deg[i2] - d2 / 2, "x", true), x1 = u.valToPos(g.theta2_deg[i2] + d2 / 2, "x", true);
        const y0 = u.valToPos(g.theta3_deg[i3] - d3 / 2, "y", true), y1 = u.valToPos(g.theta3_deg[i3] + d3 / 2, "y", true);
        const c = Math.round(40 + 210 * (kmax > kmin ? (v - kmin) / (kmax - kmin) : 1));
        ctx.fillStyle = `rgb(${c},${c},${c})`;
        ctx.fillRect(Math.min(x0, x1), Math.min(y0, y1), Math.abs(x1 - x0) + 1, Math.abs(y1 - y0) + 1);
      }
    }
    ctx.strokeStyle = "#1f78b4"; ctx.lineWidth = 1.5 * devicePixelRatio;
    ctx.fillStyle = "#1f78b4"; ctx.font = `${11 * devicePixelRatio}px sans-serif`;
    for (const z of m.zones) {
      const x0 = u.valToPos(z.q2_deg[0], "x", true), x1 = u.valToPos(z.q2_deg[1], "x", true);
      const y0 = u.valToPos(z.q3_deg[0], "y", true), y1 = u.valToPos(z.q3_deg[1], "y", true);
      ctx.strokeRect(Math.min(x0, x1), Math.min(y0, y1), Math.abs(x1 - x0), Math.abs(y1 - y0));
      ctx.fillText(z.name, Math.min(x0, x1) + 3, Math.min(y0, y1) + 12 * devicePixelRatio);
    }
    ctx.restore();
  };
  const passing = m.candidates.passing.filter((v) => v).length;
  const u = pvPlot("plan-map-fig", {
    width: 760, height: 520, mode: 1,
    scales: { x: { time: false, range: [lo2, hi2] }, y: { range: [lo3, hi3] } },
    cursor: { drag: { x: true, y: true, uni: 20 } },
    hooks: { drawClear: [drawGrid], setCursor: [(u) => planMapHover(u, pts, m)] },
    series: [{ label: "\u03b8\u2082 (deg, model)", value: (u, v) => fmt(v) },
      { label: `candidates passing the thresholds (${passing})`, stroke: "#17becf", width: 0, paths: () => null,
        points: { show: true, size: 3, fill: "#17becf", width: 0 }, value: (u, v) => fmt(v) },
      { label: `candidates rejected (${m.candidates.passing.length - passing})`, stroke: "#999999", width: 0, paths: () => null,
        points: { show: true, size: 2, fill: "#bbbbbb", width: 0 }, value: (u, v) => fmt(v), show: false },
      { label: `random zone design (${m.random.q2_deg.length})`, stroke: "#ff7f0e", width: 0, paths: () => null,
        points: { show: true, size: 9, fill: "transparent", width: 1.5 }, value: (u, v) => fmt(v) },
      { label: `${m.strategy} design (${m.chosen.q2_deg.length} poses)`, stroke: "#d62728", width: 0, paths: () => null,
        points: { show: true, size: 10, fill: "#d62728", width: 1 },
        value: (u, v, si, i) => (v === null ? "\u2013" : `${fmt(v)}, tests ${tests[i].join(", ")}`) }],
    axes: [{ label: "\u03b8\u2082 (deg, model convention)" },
           { label: "\u03b8\u2083 (deg, model convention)", size: 60 }],
  }, data);
  u.counts = { passing, rejected: m.candidates.passing.length - passing,
               random: m.random.q2_deg.length, chosen: m.chosen.q2_deg.length };
  pvEl("plan-map-caption").textContent = `1/\u03ba_F of J_N, grey from ${kmin.toFixed(3)} (dark) to ${kmax.toFixed(3)} (light), at ${m.fixed_text} ` +
    `(${m.rule_text}); boxes: the zones. Drag to zoom, double-click to reset; hover for values.`;
}

// ---- Analyze ----
async function anLoadRuns() {
  const r = await fetch("/api/runs", { credentials: "same-origin" });
  const runs = r.ok ? await r.json() : [];
  const sel = pvEl("an-run");
  const keep = sel.value;
  sel.innerHTML = "";
  for (const e of runs.filter((x) => x.kind === "run")) {
    const o = document.createElement("option");
    o.value = e.path; o.textContent = `${e.path} (${e.robot}, ${e.status})`;
    sel.appendChild(o);
  }
  if (keep) sel.value = keep;
}

function anLink(files, key, label) {
  const f = Object.entries(files).find(([k, p]) => k === key || p.endsWith(key));
  if (!f) return "";
  return `<a href="/api/runs/file?path=${encodeURIComponent(f[1])}" target="_blank" rel="noopener">${label}</a>`;
}

// acceptOnce: the "accept the refusal" button, for the refusal shown only (the CLI's
// --accept-misfit is one invocation's): the box stays as the user set it. The analysis is
// the queued analyze job of /api/jobs (the API's one path for it); its refusal's reasons
// come as records (error.refused), its progress as the job's text.
async function anRun(acceptOnce = false) {
  pvEl("an-error").textContent = "";
  pvEl("an-refused").hidden = true;
  anClear();  // the previous run's verdict, k and links are not this request's
  pvEl("an-status").textContent = "analysing\u2026";
  document.body.dataset.analyze = "running";
  const body = { run_dir: pvEl("an-run").value, method: pvEl("an-method").value,
                 robust: pvEl("an-robust").value, force: pvEl("an-force").checked,
                 accept_misfit: acceptOnce === true || pvEl("an-accept").checked };
  let d;
  try {
    d = await followJob(pvPostStatus, "/api/jobs/analyze", body,
      (j) => { if (j.text) pvEl("an-status").textContent = j.text; });
  } catch (err) {
    pvEl("an-status").textContent = "";
    const labels = fieldLabels(pvEl("an-form"));
    if (err.refused && err.refused.length) {
      const ul = pvEl("an-reasons");
      ul.innerHTML = "";
      for (const reason of err.refused) {
        const li = document.createElement("li");
        li.textContent = inFormTerms({ detail: reason.text, options: err.options }, labels);
        ul.appendChild(li);
      }
      pvEl("an-refused").hidden = false;
    } else {
      pvEl("an-error").textContent = err.detail ? inFormTerms(err, labels) : "the analysis failed";
    }
    document.body.dataset.analyze = "error";
    return;
  }
  const v = pvEl("an-verdict");
  v.textContent = d.verdict.text;
  v.className = `pv-verdict ${d.verdict.kind}`;
  const tb = document.querySelector("#an-k tbody");
  d.joints_identified.forEach((joint, i) => {
    const k = d.joint_stiffness_Nm_per_rad[i];
    const ci = d.ci95_Nm_per_rad[i] || [null, null];
    const se = d.standard_error_Nm_per_rad[i];
    const tr = document.createElement("tr");
    tr.id = `an-k${joint}`;
    const cells = [["joint", `k${joint}`], ["k", pvText(k === null ? null : k / 1e3, 1)],
      ["lo", pvText(ci[0] === null ? null : ci[0] / 1e3, 1)],
      ["hi", pvText(ci[1] === null ? null : ci[1] / 1e3, 1)],
      ["se", pvText(se === null ? null : se / 1e3, 2)]];
    for (const [c, t] of cells) {
      const td = document.createElement("td"); td.className = c; td.textContent = t; tr.appendChild(td);
    }
    tb.appendChild(tr);
  });
  pvEl("an-links").innerHTML = [anLink(d.files, "report.html", "report.html"),
    anLink(d.files, "report.pdf", "report.pdf"), anLink(d.files, "results.json", "results.json")]
    .filter((x) => x).join(" ");
  pvEl("an-status").textContent = `run ${body.run_dir}: ${d.status}` +
    (d.partial ? " (PARTIAL RUN: fewer tests than planned)" : "") +
    (d.failed_rows ? `, ${d.failed_rows} failed test row(s)` : "") +
    `; ${d.method}, robust ${body.robust}`;
  pvEl("an-force").checked = true;  // the next analysis of this run re-analyses it
  document.body.dataset.analyze = "done";
}

// the Analyze part's results emptied (a new request, or another run chosen)
function anClear() {
  const v = pvEl("an-verdict");
  v.textContent = ""; v.className = "pv-verdict";
  document.querySelector("#an-k tbody").innerHTML = "";
  pvEl("an-links").innerHTML = "";
}

function pvAddSource(name) {
  // a protocol to start from: shipped, or a workspace file (the one just saved, too)
  if ([...pvEl("plan-source").options].some((o) => o.value === name)) return;
  const o = document.createElement("option"); o.value = name; o.textContent = name;
  pvEl("plan-source").appendChild(o);
}

async function pvStart() {
  const s = await (await fetch("/api/session", { credentials: "same-origin" })).json();
  pv.csrf = s.csrf_token; pv.header = s.csrf_header;
  // the estimator and robust mode menus: the analyze job's choices and defaults, as the API
  // lists them (the same as the command line's)
  const openapi = await (await fetch("/openapi.json", { credentials: "same-origin" })).json();
  fillChoices(pvEl("an-method"), apiChoices(openapi, "AnalyzeOptions", "method"), METHOD_NOTES);
  fillChoices(pvEl("an-robust"), apiChoices(openapi, "AnalyzeOptions", "robust"));
  const plan = openapi.components.schemas.PlanRequest.properties;  // the planner's defaults
  pvEl("plan-candidates").value = String(plan.candidates.default);
  const p = await (await fetch("/api/plan/protocols", { credentials: "same-origin" })).json();
  for (const name of [...p.shipped, ...p.workspace]) pvAddSource(name);
  pvEl("plan-source").value = "kr240-2.toml";
  for (const name of p.strategies) {
    const o = document.createElement("option"); o.value = name; o.textContent = name;
    pvEl("plan-strategy").appendChild(o);
  }
  pvEl("plan-source").addEventListener("change", planLoadForm);
  pvEl("plan-run").addEventListener("click", () => planRun(false));
  pvEl("plan-save").addEventListener("click", () => planRun(true));
  pvEl("plan-compact").addEventListener("change", () =>
    pvEl("plan-fields").classList.toggle("pv-compact", pvEl("plan-compact").checked));
  pvEl("plan-target").addEventListener("change", () => { if (pv.last) planPlotSe(pv.last.summary); });
  pvEl("an-run-btn").addEventListener("click", () => anRun());
  // "Re-analyse" and "Accept" were for the run analysed: another run starts without them
  pvEl("an-run").addEventListener("change", () => {
    pvEl("an-force").checked = false; pvEl("an-accept").checked = false;
  });
  pvEl("an-refresh").addEventListener("click", anLoadRuns);
  pvEl("an-retry").addEventListener("click", () => anRun(true));
  await planLoadForm();
  await anLoadRuns();
  document.body.dataset.planview = "ready";
}

pvStart().catch((err) => { pvEl("plan-error").textContent = String(err); });
