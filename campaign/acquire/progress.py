"""Progress of a run: a live rich panel, quiet mode, or JSON lines for scripts.

The runner calls :meth:`Reporter.phase` at every phase change (with the live
wrench and deflection when known), :meth:`Reporter.event` for what also goes
to ``events.jsonl`` (tests done, retries, faults), and :meth:`Reporter.finish`
once. Units shown: deg, N, mm, s.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any, TextIO

import numpy as np


class Reporter:
    """Base reporter: keeps the state; subclasses show it."""

    def __init__(self) -> None:
        self.state: dict[str, Any] = {}
        self.t0 = time.monotonic()

    def start(self, info: dict[str, Any]) -> None:
        self.state.update(info)
        self.t0 = time.monotonic()

    def phase(self, **state: Any) -> None:
        self.state.update(state)

    def event(self, record: dict[str, Any]) -> None:
        pass

    def message(self, text: str) -> None:
        pass

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        pass

    def close(self) -> None:
        pass

    def elapsed(self) -> float:
        return time.monotonic() - self.t0

    def remaining(self) -> float | None:
        done, total = self.state.get("done", 0), self.state.get("total", 0)
        new = self.state.get("done_this_session", 0)
        if not new:
            return None
        return self.elapsed() / new * max(total - done, 0)


def _fmt_vec(v: Any, scale: float, digits: int) -> str:
    if v is None:
        return "-"
    return "[" + " ".join(f"{x * scale:.{digits}f}" for x in np.asarray(v, float)) + "]"


class QuietReporter(Reporter):
    """Prints only the final status line (stderr)."""

    def __init__(self, stream: TextIO | None = None) -> None:
        super().__init__()
        self.stream = stream or sys.stderr

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        print(f"run {status}{': ' + reason if reason else ''} ({summary.get('ok', 0)} ok, "
              f"{summary.get('failed', 0)} failed) -> {summary.get('run_dir', '')}",
              file=self.stream)


class JsonReporter(Reporter):
    """One JSON object per line on stdout: ``start``, ``phase``, events, ``finish``."""

    def __init__(self, stream: TextIO | None = None) -> None:
        super().__init__()
        self.stream = stream or sys.stdout

    def _emit(self, record: dict[str, Any]) -> None:
        self.stream.write(json.dumps(record, default=_plain) + "\n")
        self.stream.flush()

    def start(self, info: dict[str, Any]) -> None:
        super().start(info)
        self._emit({"event": "start", **info})

    def phase(self, **state: Any) -> None:
        super().phase(**state)
        self._emit({"event": "phase", "elapsed_s": round(self.elapsed(), 3),
                    "remaining_s": self.remaining(), **state})

    def event(self, record: dict[str, Any]) -> None:
        self._emit(record)

    def message(self, text: str) -> None:
        self._emit({"event": "message", "text": text})

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        self._emit({"event": "finish", "status": status, "reason": reason, **summary})


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return str(value)


class RichReporter(Reporter):
    """A live panel: test, pose, phase, wrench, deflection, elapsed and remaining time."""

    def __init__(self) -> None:
        super().__init__()
        from rich.console import Console
        from rich.live import Live

        self.console = Console(stderr=True)
        self.live: Live | None = None
        self._live_class = Live

    def start(self, info: dict[str, Any]) -> None:
        super().start(info)
        # started only now: the dry run and the confirmation prompt come before
        self.live = self._live_class(console=self.console, refresh_per_second=8,
                                     transient=True)
        self.live.start()

    def _render(self):
        from rich.table import Table

        s = self.state
        t = Table.grid(padding=(0, 2))
        t.add_column(style="bold")
        t.add_column()
        t.add_row("run", str(s.get("run_dir", "")))
        t.add_row("test", f"{s.get('test_id', '-')} (repeat {s.get('repeat', '-')}, attempt "
                          f"{s.get('attempt', '-')})  {s.get('done', 0)}/{s.get('total', 0)} done")
        t.add_row("pose", f"{s.get('pose', '-')}  q = {_fmt_vec(s.get('q_deg'), 1, 2)} deg")
        t.add_row("phase", str(s.get("phase", "-")))
        t.add_row("wrench", f"{_fmt_vec(s.get('wrench'), 1, 1)} N, N m")
        t.add_row("deflection", f"{_fmt_vec(s.get('deflection_mm'), 1, 3)} mm")
        rem = self.remaining()
        t.add_row("time", f"{self.elapsed():.1f} s elapsed, "
                          f"{'?' if rem is None else f'{rem:.0f}'} s remaining")
        return t

    def phase(self, **state: Any) -> None:
        super().phase(**state)
        if self.live is not None:
            self.live.update(self._render())

    def event(self, record: dict[str, Any]) -> None:
        kind = record.get("event")
        if kind == "test_done":
            flags = record.get("flags") or ""
            self.console.print(f"test {record['test_id']} repeat {record['repeat']}: "
                               f"{record['status']}{' [' + flags + ']' if flags else ''}")
        elif kind in ("retry", "fault", "abort", "interrupt"):
            self.console.print(f"[yellow]{kind}[/]: {record.get('reason', '')}")

    def message(self, text: str) -> None:
        self.console.print(text)

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        self.close()
        colour = "green" if status == "complete" else "red"
        self.console.print(f"[{colour}]run {status}[/]{': ' + reason if reason else ''} "
                           f"({summary.get('ok', 0)} ok, {summary.get('failed', 0)} failed, "
                           f"{self.elapsed():.1f} s) -> {summary.get('run_dir', '')}")

    def close(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None
