// campaign gui: the Fleet view. Robots of the fleet ledger (GET /api/fleet) with their last
// campaign and status; a robot's campaigns (GET /api/fleet/robot) with k per joint and its
// 95 % interval in kN m/rad, the change against the reference, alarms marked, and a link to
// each campaign's report when its files are in the workspace. Read-only.
"use strict";

function fleetKText(k, ci) {
  if (k === null || k === undefined) return "-";
  const f = (v) => (v / 1e3).toFixed(1);
  return ci ? `${f(k)} [${f(ci[0])}, ${f(ci[1])}]` : f(k);
}

function fleetCell(row, text, cls) {
  const td = document.createElement("td");
  td.textContent = text;
  if (cls) td.className = cls;
  row.appendChild(td);
  return td;
}

async function fleetJSON(url) {
  const r = await fetch(url, { credentials: "same-origin" });
  const d = await r.json();
  if (!r.ok) throw new Error(d.detail || `${url}: ${r.status}`);
  return d;
}

async function fleetLoad() {
  const err = document.getElementById("fleet-error");
  err.textContent = "";
  const d = await fleetJSON("/api/fleet");
  const body = document.querySelector("#fleet-robots tbody");
  body.innerHTML = "";
  if (!d.configured) {
    err.textContent = "no fleet ledger: start campaign gui with --db URL or set STIFFNESS_CAMPAIGN_DB";
    return;
  }
  document.getElementById("fleet-min-change").textContent = String(d.min_change_percent);
  document.getElementById("fleet-alpha").textContent = String(d.alpha);
  for (const r of d.robots) {
    const tr = document.createElement("tr");
    tr.dataset.robot = r.robot;
    const name = fleetCell(tr, "");
    const b = document.createElement("button");
    b.type = "button"; b.className = "fleet-open"; b.textContent = r.robot;
    b.addEventListener("click", () => fleetRobot(r.robot).catch((e) => { err.textContent = String(e.message || e); }));
    name.appendChild(b);
    fleetCell(tr, r.robot_model, "text");
    fleetCell(tr, String(r.campaigns));
    fleetCell(tr, `${r.last_date.slice(0, 10)} ${r.last_report_id}`, "text");
    fleetCell(tr, r.status, r.status === "alarm" ? "fleet-status alarm" : "fleet-status");
    fleetCell(tr, r.alarm_joints.join(", "), "fleet-alarm-joints");
    body.appendChild(tr);
  }
}

async function fleetRobot(robot) {
  const d = await fleetJSON(`/api/fleet/robot?robot=${encodeURIComponent(robot)}`);
  const title = document.getElementById("fleet-robot-title");
  title.hidden = false;
  title.textContent = `Robot ${d.robot}: campaigns, oldest first (reference ${d.reference})`;
  const alarmed = new Set(d.alarms.map((a) => a.joint));
  document.getElementById("fleet-alarms").textContent = d.alarms.length
    ? d.alarms.map((a) => `ALARM joint ${a.joint}: ${a.change_percent.toFixed(2)} % (${a.test})`).join("; ")
    : `no joint has dropped by more than ${d.min_change_percent} %`;
  const latest = d.check.latest;
  const table = document.getElementById("fleet-trend");
  const body = table.querySelector("tbody");
  body.innerHTML = "";
  for (const c of d.campaigns) {
    const tr = document.createElement("tr");
    tr.dataset.report = c.report_id;
    fleetCell(tr, c.date.slice(0, 10), "text");
    const rep = fleetCell(tr, "", "text");
    if (c.report) {
      const a = document.createElement("a");
      a.href = `/api/runs/file?path=${encodeURIComponent(c.report)}`;
      a.target = "_blank"; a.rel = "noopener"; a.textContent = c.report_id;
      rep.appendChild(a);
    } else {
      rep.textContent = c.report_id;
    }
    for (let j = 0; j < 6; j++) {
      const cls = c.report_id === latest && alarmed.has(j + 1) ? `k${j + 1} alarm` : `k${j + 1}`;
      fleetCell(tr, fleetKText(c.k_Nm_per_rad[j], c.ci95_Nm_per_rad[j]), cls);
    }
    fleetCell(tr, c.change_percent ? c.change_percent.map((v) => (v === null ? "-" : v.toFixed(2))).join(" ") : "-", "change");
    fleetCell(tr, c.reference ? "reference" : c.compared ? "compared" : `left out: ${c.reason}`, "text");
    body.appendChild(tr);
  }
  table.hidden = false;
}

document.getElementById("tab-fleet").addEventListener("click", () => {
  showView("fleet");  // app.js attaches its own tab handlers only once the page has started
  fleetLoad().catch((e) => { document.getElementById("fleet-error").textContent = String(e.message || e); });
});
document.getElementById("fleet-refresh").addEventListener("click", () => {
  fleetLoad().catch((e) => { document.getElementById("fleet-error").textContent = String(e.message || e); });
});
