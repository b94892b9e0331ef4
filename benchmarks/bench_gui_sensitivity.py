"""Latency of the GUI's sensitivity explorer: one slider move = one API round trip.

A GUI server (uvicorn, the app of ``campaign gui``) runs on 127.0.0.1 in a thread;
an HTTP client holding the token cookie and the CSRF header posts the settings a
user produces by moving each slider through its range (tracker translation and
rotation, F/T force and moment absolute and % of reading, encoders, number of
tests), at 1,000 trials, the KR240-2 and its zones. Baseline: the job itself
(:func:`campaign.jobs.sensitivity.run_sensitivity`) called in-process on the same
settings, interleaved, outputs compared (the API's numbers equal the job's).
Wall time per call (time.perf_counter): what the user waits for.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SWEEPS = {
    "translation_sigma_um": [10, 20, 40, 80, 160],
    "rotation_sigma_urad": [20, 50, 100, 200, 400],
    "force_sigma_N": [5, 10, 20, 40, 80],
    "force_percent": [0.1, 0.5, 1, 2, 4],
    "moment_sigma_Nm": [0.5, 1, 2.5, 5, 10],
    "moment_percent": [0.1, 0.5, 1, 2, 4],
    "encoder_resolution_deg": [0.0005, 0.001, 0.002, 0.005, 0.01],
    "n_tests": [5, 10, 15, 20, 30],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--method", default="ols", choices=["ols", "wls", "exact"])
    parser.add_argument("--repeat", type=int, default=2, help="Passes over the sweeps.")
    args = parser.parse_args()

    import httpx

    from campaign.jobs.sensitivity import run_sensitivity
    from campaign.web.security import COOKIE, CSRF_HEADER, csrf_value
    from campaign.web.sensitivity_api import SensitivityRequest, options_from_request
    from campaign.web.server import GuiOptions, make_server

    token = "bench-token-0123456789"
    ws = Path(tempfile.mkdtemp(prefix="bench-gui-"))
    srv, sock = make_server(GuiOptions(workspace=ws, port=0, open_browser=False), token)
    thread = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not srv.started:
        time.sleep(0.01)
    host, port = sock.getsockname()[:2]
    client = httpx.Client(base_url=f"http://{host}:{port}", cookies={COOKIE: token},
                          headers={CSRF_HEADER: csrf_value(token)}, timeout=60)

    bodies = [{"trials": args.trials, "method": args.method, key: v}
              for _ in range(args.repeat) for key, values in SWEEPS.items() for v in values]
    client.post("/api/sensitivity", json=bodies[0]).raise_for_status()  # warm up
    api_ms, job_ms, worst_diff = [], [], 0.0
    for body in bodies:
        t0 = time.perf_counter()
        r = client.post("/api/sensitivity", json=body)
        api_ms.append(1e3 * (time.perf_counter() - t0))
        r.raise_for_status()
        t0 = time.perf_counter()
        want = run_sensitivity(options_from_request(SensitivityRequest(**body), ws)).to_dict()
        job_ms.append(1e3 * (time.perf_counter() - t0))
        for a, b in zip(r.json()["joints"], want["joints"], strict=True):
            for key in ("median_Nm_per_rad", "std_Nm_per_rad", "predicted_se_Nm_per_rad"):
                worst_diff = max(worst_diff, abs(a[key] - b[key]) / abs(b[key]))
    srv.should_exit = True
    thread.join(10)

    def q(v, p):
        return round(statistics.quantiles(v, n=100)[p - 1], 1)

    med, job = round(statistics.median(api_ms), 1), round(statistics.median(job_ms), 1)
    print(f"{len(bodies)} slider moves at {args.trials} trials ({args.method}, KR240-2 zones)")
    print(f"API round trip: median {med} ms, p90 {q(api_ms, 90)} ms, max {max(api_ms):.1f} ms")
    print(f"job in-process: median {job} ms; HTTP + JSON overhead {med - job:.1f} ms")
    print(f"API numbers vs the job's: max relative difference {worst_diff:.1e}")
    print(json.dumps({
        "benchmark": "gui_sensitivity", "robot": "KR240-2", "poses": "zones",
        "trials": args.trials, "method": args.method, "moves": len(bodies),
        "round_trip_ms_median": med, "round_trip_ms_p90": q(api_ms, 90),
        "round_trip_ms_max": round(max(api_ms), 1), "job_ms_median": job,
        "overhead_ms_median": round(med - job, 1), "max_rel_diff": worst_diff,
        "cpus": os.cpu_count(),
        "baseline": "the job called in-process on the same settings (no HTTP, no JSON)",
        "timing": "wall time (time.perf_counter) per call, interleaved with the baseline; "
                  "server and client on 127.0.0.1 in one process (uvicorn in a thread)",
    }))


if __name__ == "__main__":
    main()
