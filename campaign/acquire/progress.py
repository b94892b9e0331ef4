"""Progress of a run: a live rich panel, quiet mode, or JSON lines for scripts.

The runner calls :meth:`Reporter.phase` at every phase change (with the live
wrench and deflection when known; None until the test at hand measured them),
:meth:`Reporter.event` for what also goes to ``events.jsonl`` (tests done,
retries, faults), and :meth:`Reporter.finish` once, with the whole run's counts
(:func:`campaign.acquire.ending.ending`). Units shown: deg, N, N m, mm, s;
joint angles in the controller (pendant) convention, as in the safety list.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO

import numpy as np

from campaign.acquire.ending import final_lines


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
    cells = (f"{x * scale:.{digits}f}" for x in np.asarray(v, float))
    # a rounded zero has no sign
    return "[" + " ".join(c[1:] if c.startswith("-") and not c.strip("-0.") else c
                          for c in cells) + "]"


@contextmanager
def interrupt_after() -> Iterator[None]:
    """Hold a Ctrl-C back until the block ends, then raise it (main thread only).

    Drawing the live panel is several writes; a KeyboardInterrupt between them
    leaves a half-drawn frame whose height the panel no longer knows, and the
    closing lines land in the middle of it. Nothing is held back when SIGINT
    is not Python's default handler (e.g. ignored while the runner makes safe).
    """
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    hit: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: hit.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if hit:
        raise KeyboardInterrupt


class QuietReporter(Reporter):
    """Prints only the final status line (stderr)."""

    def __init__(self, stream: TextIO | None = None) -> None:
        super().__init__()
        self.stream = stream or sys.stderr

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        for line in final_lines(status, reason, summary):
            print(line, file=self.stream)


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

    def __init__(self, console=None) -> None:
        super().__init__()
        from rich.console import Console
        from rich.live import Live

        self.console = console or Console(stderr=True)
        self.live: Live | None = None
        self._live_class = Live

    def start(self, info: dict[str, Any]) -> None:
        super().start(info)
        # started only now: the dry run and the confirmation prompt come before. Drawn
        # from this thread only (no refresh thread), each frame whole (interrupt_after).
        self.live = self._live_class(console=self.console, auto_refresh=False,
                                     transient=True)
        with interrupt_after():
            self.live.start()

    def _render(self):
        from rich.table import Table
        from rich.text import Text

        s = self.state
        t = Table.grid(padding=(0, 2))
        t.add_column(style="bold")
        t.add_column()
        t.add_row("run", Text(str(s.get("run_dir", ""))))
        t.add_row("test", f"{s.get('test_id', '-')} (repeat {s.get('repeat', '-')}, attempt "
                          f"{s.get('attempt', '-')})  {s.get('done', 0)}/{s.get('total', 0)} done")
        t.add_row("pose", Text(str(s.get("pose", "-"))))
        t.add_row("q (deg)", f"{_fmt_vec(s.get('q_ctrl_deg'), 1, 2)} controller convention")
        t.add_row("phase", str(s.get("phase", "-")))
        wrench, planned = s.get("wrench"), s.get("wrench_planned")
        if wrench is None and planned is not None:
            text = f"{_fmt_vec(planned, 1, 1)} N, N m (planned)"
        elif wrench is None:
            text = "- (not measured yet in this test)"
        else:
            text = f"{_fmt_vec(wrench, 1, 1)} N, N m"
        t.add_row("wrench", text)
        deflection = s.get("deflection_mm")
        t.add_row("deflection", "- (not measured yet in this test)" if deflection is None
                  else f"{_fmt_vec(deflection, 1, 3)} mm")
        rem = self.remaining()
        t.add_row("time", f"{self.elapsed():.1f} s elapsed, "
                          f"{'?' if rem is None else f'{rem:.0f}'} s remaining")
        return t

    def phase(self, **state: Any) -> None:
        super().phase(**state)
        if self.live is not None:
            with interrupt_after():
                self.live.update(self._render(), refresh=True)

    def _print(self, text: str, style: str | None = None) -> None:
        """A line above the panel (plain text: never read as markup), wrapped at words."""
        from campaign.text_wrap import print_wrapped

        with interrupt_after():
            print_wrapped(self.console, text, style=style)

    def event(self, record: dict[str, Any]) -> None:
        kind = record.get("event")
        if kind == "test_done":
            flags = record.get("flags") or ""
            self._print(f"test {record['test_id']} repeat {record['repeat']}: "
                        f"{record['status']}{' [' + flags + ']' if flags else ''}")
        elif kind in ("retry", "fault", "abort", "interrupt"):
            self._print(f"{kind}: {record.get('reason', '')}", style="yellow")

    def message(self, text: str) -> None:
        self._print(text)

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        self.close()
        lines = final_lines(status, reason, summary, self.elapsed())
        self._print(lines[0], style="green" if status == "complete" else "red")
        for line in lines[1:]:
            self._print(line, style="bold" if "STILL" in line or "NOT" in line else None)

    def close(self) -> None:
        live, self.live = self.live, None
        if live is not None:
            with interrupt_after():
                live.stop()
