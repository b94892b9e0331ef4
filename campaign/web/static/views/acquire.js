// The Acquire view: dry run, start on the simulated lab (or, confirmed, on hardware),
// live state per test from /api/acquire/events (server-sent events), abort, resume.
// State comes from the server's files (/api/acquire/state): a reload or another tab
// reattaches to the running acquisition.
(function () {
  "use strict";
  const acq = { csrf: null, header: null, source: null, run: null, timer: null };
  const el = (id) => document.getElementById(id);
  const dash = "\u2013";

  async function post(url, body) {
    if (acq.csrf === null) {
      const s = await (await fetch("/api/session")).json();
      acq.csrf = s.csrf_token; acq.header = s.csrf_header;
    }
    const r = await fetch(url, { method: "POST", body: JSON.stringify(body),
      headers: { "Content-Type": "application/json", [acq.header]: acq.csrf } });
    const doc = await r.json();
    if (!r.ok) throw new Error(doc.detail || r.statusText);
    return doc;
  }

  function vec(v, scale, digits) {
    if (!v) return dash;
    return v.map((x) => (x * scale).toFixed(digits)).join(", ");
  }

  function show(s) {
    acq.run = s.run_dir;
    el("acq-run").textContent = s.run_dir;
    el("acq-running").textContent = s.running ? "running" : "not running";
    el("acq-status").textContent = s.running ? "running" : (s.status || dash);
    // the reason a run stopped (metadata.json keeps it): not shown once it runs again
    el("acq-reason").textContent = s.running ? "" : (s.reason || s.log || "");
    const live = s.live || {};
    el("acq-stage").textContent = s.stage || dash;
    el("acq-test").textContent = live.test_id === undefined ? dash
      : `${live.test_id} (repeat ${live.repeat}, pose ${live.pose})`;
    el("acq-done").textContent = String(s.tests.filter((t) => t.status === "ok").length);
    el("acq-total").textContent = s.total === null || s.total === undefined ? dash : String(s.total);
    const w = live.wrench;
    el("acq-force").textContent = w ? vec(w.slice(0, 3), 1, 1) : dash;
    el("acq-moment").textContent = w ? vec(w.slice(3), 1, 1) : dash;
    el("acq-defl").textContent = vec(live.deflection_mm, 1, 3);
    const body = el("acq-tests").querySelector("tbody");
    body.replaceChildren(...s.tests.map((t) => {
      const tr = document.createElement("tr");
      const cells = [t.test_id, t.repeat, t.status,
        [t.fx_N, t.fy_N, t.fz_N].map((x) => x.toFixed(1)).join(", "),
        [t.mx_Nm, t.my_Nm, t.mz_Nm].map((x) => x.toFixed(1)).join(", "),
        [t.dx_mm, t.dy_mm, t.dz_mm].map((x) => x.toFixed(3)).join(", "),
        [t.rx_mrad, t.ry_mrad, t.rz_mrad].map((x) => x.toFixed(4)).join(", "),
        (t.repeatability_mm * 1000).toFixed(1), t.flags || ""];
      for (const c of cells) { const td = document.createElement("td"); td.textContent = c; tr.appendChild(td); }
      return tr;
    }));
    el("acq-abort").disabled = !s.running;
    el("acq-resume").disabled = s.running || s.status !== "aborted";
    if (window.acqMap) window.acqMap.update(s).catch(error);
  }

  async function refresh() {
    const q = acq.run ? `?run=${encodeURIComponent(acq.run)}` : "";
    const r = await fetch(`/api/acquire/state${q}`);
    if (r.status === 404 || r.status === 204) return null;  // 204: nothing started yet
    const s = await r.json();
    if (!r.ok) throw new Error(s.detail || r.statusText);
    show(s);
    return s;
  }

  function follow() {
    if (acq.source) acq.source.close();
    const src = new EventSource(`/api/acquire/events?run=${encodeURIComponent(acq.run)}`);
    acq.source = src;
    let pending = false;
    src.onmessage = () => {  // coalesce: one state read per 100 ms of event lines
      if (pending) return;
      pending = true;
      setTimeout(() => { pending = false; refresh().catch(error); }, 100);
    };
    src.addEventListener("end", () => { src.close(); acq.source = null; refresh().catch(error); });
    src.onerror = () => { src.close(); acq.source = null; setTimeout(() => refresh().catch(error), 500); };
  }

  // a refusal in the view's words: "--out" -> "New run directory", "--resume" -> "Resume"
  function error(err) {
    const text = String(err.message || err);
    el("acq-error").textContent = inFormTerms({ detail: text, options: optionsNamed(text) },
                                              fieldLabels(el("view-acquire")));
  }

  function options() {
    const scale = el("acq-scale").value.trim();
    return { fake: el("acq-fake").checked, confirm: el("acq-confirm").checked,
             time_scale: scale === "" ? null : Number(scale) };
  }

  async function dryRun() {
    el("acq-error").textContent = "";
    try {
      const d = await post("/api/acquire/dry-run", { plan: el("acq-plan").value.trim() });
      if (window.acqMap) window.acqMap.preview(el("acq-plan").value.trim());
      el("acq-motions").replaceChildren(...d.motions.filter((m) => m.trim()).map((m) => {
        const li = document.createElement("li"); li.textContent = m; return li;
      }));
    } catch (err) { error(err); }
  }

  async function begin(url, body) {
    el("acq-error").textContent = "";
    try {
      const rec = await post(url, body);
      acq.run = rec.run_dir;
      await refresh();
      follow();
    } catch (err) { error(err); }
  }

  function start() {
    const o = options();
    if (!o.fake && !o.confirm) { error("a run on hardware needs the confirmation ticked: the robot WILL move"); return; }
    begin("/api/acquire/start", { plan: el("acq-plan").value.trim(), out: el("acq-out").value.trim(), ...o });
  }

  async function abortRun() {
    try { await post("/api/acquire/abort", { run: acq.run }); } catch (err) { error(err); }
  }

  function resume() { begin("/api/acquire/resume", { run: acq.run, ...options() }); }

  async function attach() {
    // the tab works before app.js has read its API (it adds the same listener later)
    el("tab-acquire").addEventListener("click", () => {
      if (typeof showView === "function") showView("acquire");
    });
    el("acq-dry").addEventListener("click", dryRun);
    el("acq-start").addEventListener("click", start);
    el("acq-abort").addEventListener("click", abortRun);
    el("acq-resume").addEventListener("click", resume);
    el("acq-fake").addEventListener("change", () => { el("acq-confirm-row").hidden = el("acq-fake").checked; });
    el("acq-confirm-row").hidden = el("acq-fake").checked;
    try {
      const s = await refresh();  // the latest acquisition of the workspace, if any
      if (s && s.running) follow();
    } catch (err) { error(err); }
  }

  attach();
})();
