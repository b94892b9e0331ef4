"""Timed child processes for the benchmarks: CPU, peak RSS and wall time of each command.

A child forked from a large benchmark process reports that process's size as its own
peak RSS (ru_maxrss counts the pages before exec), so the commands are started from a
small launcher process, and their rusage comes from ``os.wait4`` (what
``resource.getrusage(RUSAGE_CHILDREN)`` reports for a single child).
"""

from __future__ import annotations

import json
import subprocess
import sys

#: the launcher: one JSON list of arguments per input line, one JSON result per output line
LAUNCHER = r"""
import json, os, subprocess, sys, tempfile, time
for line in sys.stdin:
    args = json.loads(line)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        print(json.dumps({"code": os.waitstatus_to_exitcode(status), "wall_s": wall,
                          "cpu_s": usage.ru_utime + usage.ru_stime,
                          "peak_rss_MB": usage.ru_maxrss / 1024,
                          "stdout": out.read().decode(errors="replace")[-2000:],
                          "stderr": err.read().decode(errors="replace")[-2000:]}), flush=True)
"""


class Launcher:
    """Runs commands from a small process; returns the rusage of each (os.wait4)."""

    def __init__(self, env: dict[str, str] | None = None) -> None:
        """``env``: the environment of the launcher and so of its commands (None: this
        process's)."""
        self.proc = subprocess.Popen([sys.executable, "-c", LAUNCHER], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, env=env)

    def run(self, args: list[str]) -> dict:
        """code, CPU (user + sys, s), peak RSS (MB), wall time (s) and the last 2000
        characters of stdout and stderr of ``args``; exit on failure."""
        self.proc.stdin.write(json.dumps([str(a) for a in args]) + "\n")
        self.proc.stdin.flush()
        out = json.loads(self.proc.stdout.readline())
        if out["code"] != 0:
            raise SystemExit(f"{' '.join(map(str, args))} failed ({out['code']}): "
                             f"{out['stderr']}")
        return out

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()
