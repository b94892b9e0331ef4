"""How an acquisition is stopped by its operator, in the words of the face that stopped it.

Ctrl-C at the terminal raises ``KeyboardInterrupt``; the web page's Abort button (and a
cancelled job) raises :class:`AbortRequested`, a ``KeyboardInterrupt`` too: both take the
same path (motion stopped, load removed, ``aborted`` recorded, resumable), and the run's
reason names the one the operator used.
"""

from __future__ import annotations

import signal


class AbortRequested(KeyboardInterrupt):
    """The operator's Abort from the web page, or the cancel of a queued job."""


def interrupt_reason(err: BaseException) -> str:
    """The reason recorded for a run the operator stopped with ``err``."""
    if isinstance(err, AbortRequested):
        return "stopped by the operator (Abort)"
    return "interrupted by the operator (Ctrl-C)"


def _abort(signum, frame) -> None:
    raise AbortRequested


def abort_on_sigint() -> None:
    """In a job's own process (no terminal: its SIGINT is the web's Abort), SIGINT raises
    :class:`AbortRequested`."""
    signal.signal(signal.SIGINT, _abort)
