"""ABB RAPID module replaying joint targets with ``MoveAbsJ`` (IRC5 / OmniCore).

Joint targets are robot axes 1..6 in degrees in the controller's (FlexPendant)
convention, stored as one ``CONST jointtarget`` array (external axes 9E+09: none).
The first and last targets are fine points, the others ``z1`` corner zones (1 mm);
speed ``v100`` (100 mm/s TCP, ABB's predefined speeddata) for a first run.
Values have five decimals: RAPID's num is a 32-bit float (about 1e-5 deg at 180 deg).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.export.robot_programs import check_targets  # one check for every program

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
NO_AXIS = "9E+09"


def write_rapid(path: str | Path, name: str, q_pendant_deg: np.ndarray,
                comments: list[str] | tuple[str, ...] = (), speed: str = "v100",
                zone: str = "z1") -> Path:
    """Write module ``NAME`` (``PROC NAME()``) to ``path`` (a ``.mod`` file).

    ``speed`` and ``zone`` are RAPID speeddata and zonedata names used between the
    first and the last target (both fine points).
    """
    if not _NAME.match(name):
        raise InputError(f"{name!r} is not a RAPID name (letter first, then letters, digits "
                         "or _, at most 32 characters)", where="program name")
    for value, what in ((speed, "speeddata"), (zone, "zonedata")):
        if not re.match(r"^[A-Za-z][A-Za-z0-9_]*$", value):
            raise InputError(f"{value!r} is not a RAPID {what} name", where=f"RAPID {what}")
    q = check_targets(q_pendant_deg, "RAPID targets")
    n = len(q)
    ext = ",".join([NO_AXIS] * 6)
    rows = [f"[[{','.join(f'{v:.5f}' for v in row)}],[{ext}]]" for row in q]
    header = [f"    ! {line}".rstrip() for text in comments for line in str(text).splitlines()]
    lines = [
        f"MODULE {name}",
        *header,
        f"    ! {n} joint targets (axes 1..6 in deg, FlexPendant convention) in {name}_jt.",
        "    ! Run it first in manual reduced speed with a low speed override.",
        "    ! MoveAbsJ moves joint-interpolated through the computed joint values;",
        "    ! check the path for collisions before running it in AUTO.",
        f"    CONST jointtarget {name}_jt{{{n}}} := [",
        *[f"        {r}{',' if i < n - 1 else ''}" for i, r in enumerate(rows)],
        "    ];",
        "",
        f"    PROC {name}()",
    ]
    if n > 2:  # (RAPID's FOR counts down when FROM > TO: no loop without middle points)
        lines += ["        VAR num i;",
                  f"        MoveAbsJ {name}_jt{{1}}, {speed}, fine, tool0;",
                  f"        FOR i FROM 2 TO {n - 1} DO",
                  f"            MoveAbsJ {name}_jt{{i}}, {speed}, {zone}, tool0;",
                  "        ENDFOR"]
    elif n == 2:
        lines.append(f"        MoveAbsJ {name}_jt{{1}}, {speed}, fine, tool0;")
    lines += [f"        MoveAbsJ {name}_jt{{{n}}}, {speed}, fine, tool0;",
              "    ENDPROC", "ENDMODULE", ""]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines).replace("\n", "\r\n"))
    return path
