"""Fault injection shared by the fake instruments.

A fault is armed for a device with a count (how many packets/replies it
affects) or ``-1`` for "until cleared". Fakes ask :meth:`Faults.take` at each
packet; it consumes one occurrence and says whether to misbehave.

Faults understood by the fakes:

``drop``        skip outgoing packets/replies
``late``        send an old packet again (out of order / late)
``garbage``     send random bytes instead of a packet
``bad_crc``     corrupt the checksum (serial)
``disconnect``  close the connection / stop answering for good
``frozen``      repeat the same measured values
``beam_lost``   tracker: report that the beam is lost
"""

from __future__ import annotations

import threading

KNOWN_FAULTS = ("drop", "late", "garbage", "bad_crc", "disconnect", "frozen", "beam_lost")


class Faults:
    """Thread-safe table device -> fault -> remaining count."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._armed: dict[str, dict[str, int]] = {}

    def inject(self, device: str, fault: str, count: int = 1) -> None:
        """Arm ``fault`` on ``device`` for ``count`` occurrences (-1: until cleared)."""
        if fault not in KNOWN_FAULTS:
            raise ValueError(f"unknown fault {fault!r}; known: {', '.join(KNOWN_FAULTS)}")
        if count == 0 or count < -1:
            raise ValueError("count must be positive or -1")
        with self._lock:
            self._armed.setdefault(device, {})[fault] = int(count)

    def clear(self, device: str | None = None) -> None:
        """Disarm every fault (of one device, or of all)."""
        with self._lock:
            if device is None:
                self._armed.clear()
            else:
                self._armed.pop(device, None)

    def active(self, device: str, fault: str) -> bool:
        """Whether ``fault`` is armed on ``device`` (without consuming it)."""
        with self._lock:
            return self._armed.get(device, {}).get(fault, 0) != 0

    def take(self, device: str, fault: str) -> bool:
        """Consume one occurrence of ``fault`` on ``device``; True if it was armed."""
        with self._lock:
            table = self._armed.get(device, {})
            left = table.get(fault, 0)
            if left == 0:
                return False
            if left > 0:
                table[fault] = left - 1
            return True
