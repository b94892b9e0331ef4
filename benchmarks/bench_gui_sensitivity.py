"""Latency of the GUI's sensitivity explorer: one slider move = one API round trip.

``campaign gui --port 0 --no-browser`` runs as its own process on 127.0.0.1 (as a
user starts it); an HTTP client holding the token cookie and the CSRF header posts
the settings a
user produces by moving each slider through its range (tracker translation and
rotation, F/T force and moment absolute and % of reading, encoders, number of
tests), at 1,000 trials, the KR240-2 and its zones. Baseline: the job itself
(:func:`campaign.jobs.sensitivity.run_sensitivity`) called in-process on the same
settings, interleaved, outputs compared (the API's numbers equal the job's).
Wall time per call (time.perf_counter): what the user waits for.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _load import LoadWindow

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
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--method", default="ols", choices=["ols", "wls", "exact"])
    parser.add_argument("--repeat", type=int, default=2, help="Passes over the sweeps.")
    args = parser.parse_args()

    from campaign.jobs.sensitivity import run_sensitivity
    from campaign.web.security import COOKIE, CSRF_HEADER, csrf_value
    from campaign.web.sensitivity_api import SensitivityRequest, options_from_request

    ws = Path(tempfile.mkdtemp(prefix="bench-gui-"))
    server = subprocess.Popen(
        [sys.executable, "-m", "campaign", "gui", "--workspace", str(ws), "--port", "0",
         "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        url = _url(server)
        base, token = url.split("/?token=")
        client = _Client(base, {"Cookie": f"{COOKIE}={token}",
                                CSRF_HEADER: csrf_value(token)})
        api_ms, job_ms, worst_diff, bodies, server_cpu_ms, job_cpu_ms = _measure(
            client, args, ws, run_sensitivity, SensitivityRequest, options_from_request,
            server.pid)
    finally:
        server.terminate()
        server.wait(10)

    def q(v, p):
        return round(statistics.quantiles(v, n=100)[p - 1], 1)

    med, job = round(statistics.median(api_ms), 1), round(statistics.median(job_ms), 1)
    print(f"{len(bodies)} slider moves at {args.trials} trials ({args.method}, KR240-2 zones)")
    print(f"API round trip: median {med} ms, p90 {q(api_ms, 90)} ms, max {max(api_ms):.1f} ms")
    print(f"job in-process: median {job} ms; HTTP + JSON overhead {med - job:.1f} ms")
    print(f"API numbers vs the job's: max relative difference {worst_diff:.1e}")
    cpu = {}
    if server_cpu_ms:
        # what the server computes per move, whatever else the machine runs: on a loaded
        # machine the wall time is this CPU time plus the wait for a core
        cpu = {"server_cpu_ms_median": round(statistics.median(server_cpu_ms), 1),
               "server_cpu_ms_p90": q(server_cpu_ms, 90)}
        print(f"server CPU per move: median {cpu['server_cpu_ms_median']} ms, "
              f"p90 {cpu['server_cpu_ms_p90']} ms (user + system, /proc)")
    cpu["job_cpu_ms_median"] = round(statistics.median(job_cpu_ms), 1)
    load.emit({
        "benchmark": "gui_sensitivity", "robot": "KR240-2", "poses": "zones",
        "trials": args.trials, "method": args.method, "moves": len(bodies),
        "round_trip_ms_median": med, "round_trip_ms_p90": q(api_ms, 90),
        "round_trip_ms_max": round(max(api_ms), 1), "job_ms_median": job,
        "overhead_ms_median": round(med - job, 1), "max_rel_diff": worst_diff, **cpu,
        "cpus": os.cpu_count(),
        "baseline": "the job called in-process on the same settings (no HTTP, no JSON)",
        "timing": "wall time (time.perf_counter) per call, interleaved with the baseline; "
                  "the server is `campaign gui` in its own process on 127.0.0.1",
    })


class _Client:
    """One kept-alive HTTP/1.1 connection with TCP_NODELAY, as a browser holds: without
    it, Nagle's algorithm and delayed ACKs add ~40 ms to every small request."""

    def __init__(self, base: str, headers: dict) -> None:
        import http.client
        import socket
        from urllib.parse import urlsplit

        u = urlsplit(base)
        self.conn = http.client.HTTPConnection(u.hostname, u.port, timeout=60)
        self.conn.connect()
        self.conn.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.headers = {**headers, "Content-Type": "application/json"}

    def post(self, path: str, json: dict) -> dict:
        import json as js

        self.conn.request("POST", path, body=js.dumps(json), headers=self.headers)
        r = self.conn.getresponse()
        data = r.read()
        if r.status != 200:
            raise SystemExit(f"{path}: HTTP {r.status}: {data[:200]!r}")
        return js.loads(data)


def _url(server) -> str:
    """The URL `campaign gui` prints (its line ``open http://...``)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = server.stdout.readline()
        if not line:
            break
        if line.startswith("open http"):
            return line.split()[1]
    raise SystemExit("campaign gui did not print its URL")


def _process_cpu_s(pid: int) -> float | None:
    """User + system CPU time (s) of process ``pid`` so far (Linux /proc; None elsewhere)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _measure(client, args, ws, run_sensitivity, SensitivityRequest, options_from_request,
             server_pid: int):
    bodies = [{"trials": args.trials, "method": args.method, key: v}
              for _ in range(args.repeat) for key, values in SWEEPS.items() for v in values]
    client.post("/api/sensitivity", json=bodies[0])  # warm up
    api_ms, job_ms, worst_diff, server_cpu_ms, job_cpu_ms = [], [], 0.0, [], []
    for body in bodies:
        c0 = _process_cpu_s(server_pid)
        t0 = time.perf_counter()
        got = client.post("/api/sensitivity", json=body)
        api_ms.append(1e3 * (time.perf_counter() - t0))
        c1 = _process_cpu_s(server_pid)
        if c0 is not None and c1 is not None:
            server_cpu_ms.append(1e3 * (c1 - c0))
        t0, c0 = time.perf_counter(), time.process_time()
        want = run_sensitivity(options_from_request(SensitivityRequest(**body), ws)).to_dict()
        job_ms.append(1e3 * (time.perf_counter() - t0))
        job_cpu_ms.append(1e3 * (time.process_time() - c0))
        for a, b in zip(got["joints"], want["joints"], strict=True):
            for key in ("median_Nm_per_rad", "std_Nm_per_rad", "predicted_se_Nm_per_rad"):
                worst_diff = max(worst_diff, abs(a[key] - b[key]) / abs(b[key]))
    return api_ms, job_ms, worst_diff, bodies, server_cpu_ms, job_cpu_ms


if __name__ == "__main__":
    main()
