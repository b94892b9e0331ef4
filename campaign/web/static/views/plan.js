// campaign gui: the Plan and Analyze views (their own file; app.js is untouched).
// POSTs carry the CSRF header of /api/session.
"use strict";

const pv = { csrf: null, header: null };

function pvEl(id) { return document.getElementById(id); }

async function pvPost(url, body) {
  const r = await fetch(url, { method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", [pv.header]: pv.csrf },
    body: JSON.stringify(body) });
  return [r.ok, await r.json()];
}

function pvText(v, digits) { return v === null || v === undefined ? "\u2013" : v.toFixed(digits); }

// ---- Plan ----
async function planLoadForm() {
  const src = pvEl("plan-source").value;
  const r = await fetch(`/api/plan/form?source=${encodeURIComponent(src)}`, { credentials: "same-origin" });
  const d = await r.json();
  const box = pvEl("plan-fields");
  box.innerHTML = "";
  if (!r.ok) { pvEl("plan-error").textContent = d.detail; return; }
  for (const f of d.fields) {
    const row = document.createElement("label");
    row.className = "pv-field";
    row.dataset.key = f.key;
    row.innerHTML = `<span></span><input><small class="pv-msg" role="alert"></small>`;
    row.querySelector("span").textContent = `${f.label} [${f.key}]`;
    const input = row.querySelector("input");
    input.id = "pf-" + f.key.replaceAll(".", "-");
    input.value = f.value;
    input.dataset.key = f.key;
    input.dataset.original = f.value;
    box.appendChild(row);
  }
}

function planBody() {
  const values = {};
  for (const input of document.querySelectorAll("#plan-fields input")) {
    if (input.value !== input.dataset.original) values[input.dataset.key] = input.value;
  }
  return { source: pvEl("plan-source").value, values, name: pvEl("plan-name").value.trim(),
           strategy: pvEl("plan-strategy").value, seed: Number(pvEl("plan-seed").value),
           candidates: Number(pvEl("plan-candidates").value) };
}

function planClearMessages() {
  pvEl("plan-error").textContent = "";
  for (const m of document.querySelectorAll("#view-plan .pv-msg")) m.textContent = "";
  for (const m of document.querySelectorAll("#view-plan .pv-bad")) m.classList.remove("pv-bad");
}

async function planRun() {
  planClearMessages();
  pvEl("plan-status").textContent = "planning\u2026";
  document.body.dataset.plan = "running";
  const [ok, d] = await pvPost("/api/plan/run", planBody());
  if (!ok) {
    const row = d.field && document.querySelector(`#view-plan [data-key="${d.field}"]`);
    const msg = row && row.querySelector(".pv-msg");
    if (msg) { msg.textContent = d.detail; row.classList.add("pv-bad"); }
    else pvEl("plan-error").textContent = d.detail || "the plan failed";
    pvEl("plan-status").textContent = "";
    document.body.dataset.plan = "error";
    return;
  }
  planShow(d);
  document.body.dataset.plan = "done";
}

function planShow(d) {
  const s = d.summary;
  pvEl("plan-status").textContent = `${s.tests} tests at ${s.poses} poses of ${s.robot} ` +
    `(${s.strategy}, ${s.candidates.poses_passing} of ${s.candidates.drawn} candidates pass); ` +
    `saved ${d.protocol} and ${d.out}/`;
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
    const bar = document.createElement("td");
    bar.className = "bar";
    const w = Math.min(100, 20 * (j.se_design_percent || 0));
    bar.innerHTML = `<span class="pv-bar" style="width:${w}%"></span>`;
    tr.appendChild(bar);
    tb.appendChild(tr);
  }
  const pb = document.querySelector("#plan-rows tbody");
  pb.innerHTML = "";
  for (const r of d.rows) {
    const tr = document.createElement("tr");
    tr.className = "plan-row";
    const q = [1, 2, 3, 4, 5, 6].map((i) => pvText(r[`q${i}_model_deg`], 3)).join(", ");
    for (const t of [r.test, r.zone, r.load_case, q, pvText(r.inv_kappa_F, 4)]) {
      const td = document.createElement("td"); td.textContent = String(t); tr.appendChild(td);
    }
    pb.appendChild(tr);
  }
  const map = d.files.find((f) => f.endsWith("plan_map.png"));
  const img = pvEl("plan-map");
  if (map) { img.src = `/api/runs/file?path=${encodeURIComponent(map)}&t=${Date.now()}`; img.hidden = false; }
  else img.hidden = true;
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

async function anRun() {
  pvEl("an-error").textContent = "";
  pvEl("an-refused").hidden = true;
  pvEl("an-status").textContent = "analysing\u2026";
  document.body.dataset.analyze = "running";
  const body = { run_dir: pvEl("an-run").value, method: pvEl("an-method").value,
                 robust: pvEl("an-robust").value, force: pvEl("an-force").checked,
                 accept_misfit: pvEl("an-accept").checked };
  const [ok, d] = await pvPost("/api/analyze/run", body);
  pvEl("an-status").textContent = "";
  if (!ok) {
    if (d.refused && d.refused.length) {
      const ul = pvEl("an-reasons");
      ul.innerHTML = "";
      for (const reason of d.refused) {
        const li = document.createElement("li"); li.textContent = reason; ul.appendChild(li);
      }
      pvEl("an-refused").hidden = false;
    } else {
      pvEl("an-error").textContent = d.detail || "the analysis failed";
    }
    document.body.dataset.analyze = "error";
    return;
  }
  const v = pvEl("an-verdict");
  v.textContent = d.verdict.text;
  v.className = `pv-verdict ${d.verdict.kind}`;
  const tb = document.querySelector("#an-k tbody");
  tb.innerHTML = "";
  for (const j of d.joints) {
    const tr = document.createElement("tr");
    tr.id = `an-k${j.joint}`;
    const ci = j.ci95_Nm_per_rad || [null, null];
    const cells = [["joint", `k${j.joint}`], ["k", pvText(j.k_Nm_per_rad / 1e3, 1)],
      ["lo", pvText(ci[0] === null ? null : ci[0] / 1e3, 1)],
      ["hi", pvText(ci[1] === null ? null : ci[1] / 1e3, 1)],
      ["se", pvText(j.se_Nm_per_rad === null ? null : j.se_Nm_per_rad / 1e3, 2)]];
    for (const [c, t] of cells) {
      const td = document.createElement("td"); td.className = c; td.textContent = t; tr.appendChild(td);
    }
    tb.appendChild(tr);
  }
  pvEl("an-links").innerHTML = [anLink(d.files, "report.html", "report.html"),
    anLink(d.files, "report.pdf", "report.pdf"), anLink(d.files, "results.json", "results.json")]
    .filter((x) => x).join(" ");
  const run = d.run || {};
  pvEl("an-status").textContent = `run ${body.run_dir}: ${run.status}` +
    (run.partial ? " (PARTIAL RUN: fewer tests than planned)" : "") +
    (run.failed_rows ? `, ${run.failed_rows} failed test row(s)` : "") +
    `; ${d.method}, robust ${body.robust}`;
  pvEl("an-force").checked = true;  // the next run of this view re-analyses
  document.body.dataset.analyze = "done";
}

async function pvStart() {
  const s = await (await fetch("/api/session", { credentials: "same-origin" })).json();
  pv.csrf = s.csrf_token; pv.header = s.csrf_header;
  const p = await (await fetch("/api/plan/protocols", { credentials: "same-origin" })).json();
  for (const name of [...p.shipped, ...p.workspace]) {
    const o = document.createElement("option"); o.value = name; o.textContent = name;
    pvEl("plan-source").appendChild(o);
  }
  pvEl("plan-source").value = "kr240-2.toml";
  for (const name of p.strategies) {
    const o = document.createElement("option"); o.value = name; o.textContent = name;
    pvEl("plan-strategy").appendChild(o);
  }
  pvEl("plan-source").addEventListener("change", planLoadForm);
  pvEl("plan-run").addEventListener("click", planRun);
  pvEl("an-run-btn").addEventListener("click", anRun);
  pvEl("an-refresh").addEventListener("click", anLoadRuns);
  pvEl("an-retry").addEventListener("click", () => { pvEl("an-accept").checked = true; anRun(); });
  await planLoadForm();
  await anLoadRuns();
  document.body.dataset.planview = "ready";
}

pvStart().catch((err) => { pvEl("plan-error").textContent = String(err); });
