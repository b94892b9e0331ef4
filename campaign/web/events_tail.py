"""The summary of an acquisition's events file, read from where the last reading stopped.

``GET /api/acquire/state`` needs of the events file (JSON lines, appended by the
job's process) only the last ``start`` line, the ``phase`` lines folded into the
live state, and the last ``finish`` line. Reading the whole file per call costs
O(events) per poll; :class:`EventsTail` remembers the byte offset after the last
complete line and the summary so far, and reads only what was appended since.
The answer is the one a full reading gives: a trailing line the writer has not
finished is folded into the answer if it parses (as a full reading would) but
not into the remembered summary, and a file that shrank or was replaced (another
inode) is read again from its start.

The tails of one server live in its app (:func:`tails_of`: ``app.state``), not in
this module; a restarted server starts with none and reads each file once in full.
"""

from __future__ import annotations

import contextlib
import copy
import json
import os
import threading
from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

#: events files whose tails a server keeps (the least recently read are let go)
MAX_TAILS = 64


@dataclass
class EventsSummary:
    """start: the last ``start`` line; live: the ``live_keys`` of the ``phase`` lines,
    each the latest value; finish: the last ``finish`` line (None while running)."""

    start: dict = field(default_factory=dict)
    live: dict = field(default_factory=dict)
    finish: dict | None = None

    def fold(self, line: dict, live_keys: Iterable[str]) -> None:
        """Take one event line into the summary."""
        kind = line.get("event")
        if kind == "start":
            self.start = line
        elif kind == "phase":
            self.live.update({k: v for k, v in line.items() if k in live_keys})
        elif kind == "finish":
            self.finish = line


def parse(raw: bytes) -> dict | None:
    """One line as a JSON object, or None (blank, cut short, not an object)."""
    try:
        value = json.loads(raw.decode("utf-8", "replace"))
    except ValueError:
        return None
    return value if isinstance(value, dict) else None


def summarize(path: Path, live_keys: Iterable[str]) -> EventsSummary:
    """The summary of the whole file read at once (the reference :class:`EventsTail`
    agrees with)."""
    keys = frozenset(live_keys)
    summary = EventsSummary()
    with contextlib.suppress(OSError):
        for raw in Path(path).read_bytes().splitlines():
            line = parse(raw)
            if line is not None:
                summary.fold(line, keys)
    return summary


class EventsTail:
    """One events file's summary up to :attr:`offset` (bytes, after a complete line)."""

    def __init__(self, path: Path, live_keys: Iterable[str]) -> None:
        self.path = Path(path)
        self.keys = frozenset(live_keys)
        self.offset = 0
        self.identity: tuple[int, int] | None = None
        self.summary = EventsSummary()
        self.lock = threading.Lock()

    def read(self) -> EventsSummary:
        """The summary of the file as it is now (a copy: the caller may keep it)."""
        with self.lock:
            try:
                with open(self.path, "rb") as f:
                    st = os.fstat(f.fileno())
                    if (st.st_dev, st.st_ino) != self.identity or st.st_size < self.offset:
                        self.identity, self.offset = (st.st_dev, st.st_ino), 0
                        self.summary = EventsSummary()
                    f.seek(self.offset)
                    chunk = f.read()
            except OSError:
                self.identity, self.offset, self.summary = None, 0, EventsSummary()
                return EventsSummary()
            end = chunk.rfind(b"\n") + 1  # complete lines: up to the last newline
            for raw in chunk[:end].splitlines():
                line = parse(raw)
                if line is not None:
                    self.summary.fold(line, self.keys)
            self.offset += end
            answer = copy.deepcopy(self.summary)
        rest = parse(chunk[end:])  # a last line without its newline yet
        if rest is not None:
            answer.fold(rest, self.keys)
        return answer


class EventsTails:
    """The :class:`EventsTail` of each events file a server reads, at most :data:`MAX_TAILS`."""

    def __init__(self, live_keys: Iterable[str], limit: int = MAX_TAILS) -> None:
        self.keys = tuple(live_keys)
        self.limit = limit
        self._tails: OrderedDict[Path, EventsTail] = OrderedDict()
        self._lock = threading.Lock()

    def read(self, path: Path) -> EventsSummary:
        """The summary of the events file ``path`` (read from where its last reading stopped)."""
        path = Path(path)
        with self._lock:
            tail = self._tails.pop(path, None) or EventsTail(path, self.keys)
            self._tails[path] = tail  # the most recently read last
            while len(self._tails) > self.limit:
                self._tails.popitem(last=False)
        return tail.read()


_creating = threading.Lock()


def tails_of(app, live_keys: Iterable[str]) -> EventsTails:
    """The app's :class:`EventsTails` (made at its first use, kept in ``app.state``)."""
    with _creating:
        tails = getattr(app.state, "events_tails", None)
        if tails is None:
            tails = app.state.events_tails = EventsTails(live_keys)
        return tails
