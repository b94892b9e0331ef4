"""Benchmark: the 5-pose KR240-2 campaign on the simulated lab, end to end over loopback.

Runs the built-in protocol's plan (5 tests x 3 repeats) with ``campaign acquire --fake``
at two time scales s1 < s2 in the same process. Wall time is modelled as
``T(s) = overhead + lab_time / s``: ``lab_time`` is the simulated robot's own time
(motions and settling, seconds of robot time), ``overhead`` what the software and the
loopback protocols add. Prints both runs, the two fitted figures and the time at
each scale as a multiple of the overhead.

Run: ``python benchmarks/bench_fake_campaign.py [--scales 50 200]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from campaign.acquire.progress import QuietReporter
from campaign.acquire.session import AcquireOptions, acquire
from campaign.planner import make_plan, write_plan
from campaign.protocol import load_protocol

PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "kr240-2.toml"


def run(plan: Path, out: Path, scale: float) -> float:
    t0 = time.perf_counter()
    outcome = acquire(plan, out, None, AcquireOptions(fake=True, assume_yes=True,
                                                      time_scale=scale),
                      QuietReporter(), say=lambda s: None)
    elapsed = time.perf_counter() - t0
    if outcome.status != "complete":
        raise SystemExit(f"campaign {outcome.status}: {outcome.reason}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scales", type=float, nargs=2, default=(50.0, 200.0))
    args = parser.parse_args()
    s1, s2 = sorted(args.scales)
    with tempfile.TemporaryDirectory() as tmp:
        plan = Path(tmp) / "plan"
        write_plan(make_plan(load_protocol(PROTOCOL)), plan, figure=False)
        t1 = run(plan, Path(tmp) / "run1", s1)
        t2 = run(plan, Path(tmp) / "run2", s2)
    lab_time = (t1 - t2) / (1 / s1 - 1 / s2)
    overhead = t1 - lab_time / s1
    print(f"5 tests x 3 repeats: {t1:.1f} s at time scale {s1:g}, {t2:.1f} s at {s2:g}")
    print(f"simulated robot time (motions, settling): {lab_time:.0f} s of robot time")
    print(f"software and loopback overhead: {overhead:.1f} s")
    print(f"wall time / overhead: {t1 / overhead:.2f} at scale {s1:g}, "
          f"{t2 / overhead:.2f} at scale {s2:g}")


if __name__ == "__main__":
    main()
