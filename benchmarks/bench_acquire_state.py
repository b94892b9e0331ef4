"""Benchmark: GET /api/acquire/state's reading of the events file, full vs incremental.

Work measured: the summary the state needs (last ``start`` line, the ``phase``
lines folded into the live state, the ``finish`` line) of an events file of
``--events`` lines as ``campaign acquire --json`` writes them, while the job
appends one line between two polls.

* Full: :func:`campaign.web.events_tail.summarize`, the whole file read and
  parsed per poll (what the endpoint did before).
* Incremental: :class:`campaign.web.events_tail.EventsTail`, which reads only
  the bytes appended since its last reading.

Both are timed the same way (wall and CPU time per poll, best of ``--repeat``
rounds of ``--polls`` polls, interleaved), and each incremental answer is
compared with the full reading of the same file before any figure is printed.
Run: ``python benchmarks/bench_acquire_state.py [--events 10000]``; the last line
printed is one JSON object with the figures.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from campaign.web.acquire_api import LIVE  # noqa: E402
from campaign.web.events_tail import EventsTail, summarize  # noqa: E402
from tests.web.test_acquire_state_tail import events_text  # noqa: E402


def _timed(fn) -> tuple[float, float]:
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--events", type=int, default=10_000)
    ap.add_argument("--polls", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    lines = events_text(args.events + args.polls * args.repeat * 2).splitlines(keepends=True)
    head, extra = lines[:args.events], iter(lines[args.events:])
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "events.jsonl"
        path.write_text("".join(head))
        size = path.stat().st_size
        tail = EventsTail(path, LIVE)
        tail.read()  # the first reading of a server is a full one
        full_w, full_c, inc_w, inc_c = [], [], [], []
        for _ in range(args.repeat):
            for timings, reader in (((full_w, full_c), lambda: summarize(path, LIVE)),
                                    ((inc_w, inc_c), tail.read)):
                w_sum = c_sum = 0.0
                for _ in range(args.polls):
                    with open(path, "a") as f:
                        f.write(next(extra))
                    answer = {}
                    w, c = _timed(lambda reader=reader, answer=answer:
                                  answer.setdefault("a", reader()))
                    w_sum, c_sum = w_sum + w, c_sum + c
                    assert answer["a"] == summarize(path, LIVE), "answers differ"
                timings[0].append(w_sum / args.polls)
                timings[1].append(c_sum / args.polls)
    figures = {"benchmark": "acquire_state", "events": args.events, "file_bytes": size,
               "polls": args.polls, "repeat": args.repeat,
               "full_ms_per_poll": round(min(full_w) * 1e3, 3),
               "full_cpu_ms_per_poll": round(min(full_c) * 1e3, 3),
               "incremental_ms_per_poll": round(min(inc_w) * 1e3, 4),
               "incremental_cpu_ms_per_poll": round(min(inc_c) * 1e3, 4),
               "ratio_wall": round(min(full_w) / min(inc_w), 1), "answers_equal": True}
    print(f"{args.events} events ({size / 1e6:.2f} MB): full reading "
          f"{figures['full_ms_per_poll']} ms/poll, incremental "
          f"{figures['incremental_ms_per_poll']} ms/poll")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
