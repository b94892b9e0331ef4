"""The machine's load around a benchmark, for its JSON line.

The development machine is shared: a benchmark's figures mean something only
beside the load they were measured under. :class:`LoadWindow` reads the
1-minute load average when a benchmark starts and again when it prints its
last line; :meth:`LoadWindow.emit` prints that line with both.
"""

from __future__ import annotations

import json
import os


class LoadWindow:
    """1-minute load average at the start of a benchmark and at its end."""

    def __init__(self) -> None:
        self.before = round(os.getloadavg()[0], 2)

    def emit(self, figures: dict) -> None:
        """Print ``figures`` as the benchmark's last line: one JSON object, with
        ``load_average_1min`` = [at the start, now]."""
        after = round(os.getloadavg()[0], 2)
        print(json.dumps({**figures, "load_average_1min": [self.before, after]}), flush=True)
