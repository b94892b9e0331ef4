"""The jobs' progress hooks, given a queued job's :class:`~campaign.web.job_queue.Progress`.

The jobs report as the command line shows them (``stage(text)`` around a long
step, ``note(line)``, a rich console's lines, an acquisition's reporter); these
turn each into the job's progress record, where a cancellation then takes
effect (except in the acquisition, which polls ``cancelled()`` at its phases and
takes its own Ctrl-C path).
"""

from __future__ import annotations

import io
from contextlib import contextmanager

from campaign.acquire.progress import Reporter
from campaign.web.job_queue import Progress


def stage(progress: Progress):
    """A job's ``stage(text)`` hook: the step's text as progress (fraction unknown)."""

    @contextmanager
    def hook(text: str):
        progress.report(None, text)
        yield
    return hook


def say(progress: Progress):
    """A job's ``note(line)`` hook: the line as progress, the fraction kept."""

    def hook(text: str) -> None:
        progress.report(progress.fraction, " ".join(str(text).split()))
    return hook


class _Lines(io.TextIOBase):
    """A text stream whose complete lines become progress lines."""

    def __init__(self, progress: Progress) -> None:
        self.progress, self.part = progress, ""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        self.part += text
        *lines, self.part = self.part.split("\n")
        for line in lines:
            if line.strip():
                say(self.progress)(line)
        return len(text)


def console(progress: Progress):
    """A rich Console whose printed lines become the job's progress lines."""
    from rich.console import Console

    return Console(file=_Lines(progress), width=200, color_system=None,
                   force_terminal=False)


class AcquireProgress(Reporter):
    """An acquisition's reporter: each phase as progress (tests done / total)."""

    def __init__(self, progress: Progress) -> None:
        super().__init__()
        self.progress = progress

    def phase(self, **state) -> None:
        super().phase(**state)
        s = self.state
        done, total = s.get("done", 0), s.get("total", 0)
        self.progress.note(done / total if total else None,
                           f"test {s.get('test_id', '-')}: {s.get('phase', '')} "
                           f"({done} of {total or '?'} done)")
