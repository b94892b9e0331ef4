// campaign gui: the robot pickers' choices (Sensitivity, Plan, Use) from /api/robots,
// and the URDF upload of the Sensitivity form. A choice's value is the robot text a job
// takes: a built-in name, a workspace robot file, or robots/arm.urdf#tool0.
"use strict";

async function robotChoices() {
  const r = await fetch("/api/robots", { credentials: "same-origin" });
  if (!r.ok) throw new Error(`/api/robots: ${r.status}`);
  return (await r.json()).robots;
}

function robotFillDatalist(list, choices) {
  list.innerHTML = "";
  for (const c of choices) {
    const o = document.createElement("option");
    o.value = c.value; o.label = c.label; o.dataset.kind = c.kind;
    list.appendChild(o);
  }
}

async function robotUpload(input, tipInput, msg, onSaved) {
  msg.textContent = "";
  const file = input.files && input.files[0];
  if (!file) { msg.textContent = "choose a .urdf file first"; return; }
  const s = await (await fetch("/api/session", { credentials: "same-origin" })).json();
  const body = { name: file.name, text: await file.text(), replace: true };
  if (tipInput.value.trim()) body.tip = tipInput.value.trim();
  const r = await fetch("/api/robots/urdf", { method: "POST", credentials: "same-origin",
    headers: { "Content-Type": "application/json", [s.csrf_header]: s.csrf_token },
    body: JSON.stringify(body) });
  const d = await r.json();
  if (!r.ok) { msg.textContent = d.detail || r.statusText; msg.dataset.state = "error"; return; }
  await onSaved(d.robots[0].value);
  msg.textContent = `saved ${d.saved}; offered as ${d.robots.map((c) => c.value).join(", ")}`;
  msg.dataset.state = "saved";
}
