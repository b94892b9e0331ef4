"""FANUC teach-pendant program in ASCII form (``.LS``) replaying joint targets.

Layout of FANUC's ASCII program format (R-30iB; loaded with the ASCII Upload option
or converted to ``.TP`` by ROBOGUIDE / ``maketp``): ``/PROG name``, ``/ATTR`` (owner,
comment, line count, default group), ``/MN`` with numbered lines (``J P[i] 10% FINE ;``
joint motions, ``! text ;`` remarks), ``/POS`` with one ``P[i]{ GP1: UF, UT, J1..J6 }``
in joint representation, ``/END``.

Joint values are degrees in the controller's convention (J3 relative to the horizontal
on arms with J2/J3 interaction), three decimals as FANUC writes them (0.0005 deg of
rounding). The first and last points are ``FINE``, the others ``CNT`` (default 10);
speed in percent of the joint maxima. Remarks are wrapped at 32 characters (the
pendant's comment length).
"""

from __future__ import annotations

import datetime
import re
import textwrap
from pathlib import Path

import numpy as np

from analysis.errors import InputError

_NAME = re.compile(r"^[A-Z][A-Z0-9_]{0,35}$")
REMARK = 32


def _remarks(comments) -> list[str]:
    out = []
    for text in comments:
        for line in str(text).splitlines():
            line = line.replace(";", ",").strip()
            out += textwrap.wrap(line, REMARK, break_long_words=True) or [""]
    return out


def write_fanuc_ls(path: str | Path, name: str, q_pendant_deg: np.ndarray,
                   comments: list[str] | tuple[str, ...] = (), speed_percent: int = 10,
                   cnt: int = 10, uframe: int = 0, utool: int = 1) -> Path:
    """Write ``NAME.LS`` (program ``NAME``, upper case) to ``path``."""
    name = name.upper()
    if not _NAME.match(name):
        raise InputError(f"{name!r} is not a FANUC program name (letter first, then letters, "
                         "digits or _, at most 36 characters)", where="program name")
    if not (isinstance(speed_percent, int) and 1 <= speed_percent <= 100):
        raise InputError("expected a joint speed of 1..100 %", where="FANUC speed")
    if not (isinstance(cnt, int) and 0 <= cnt <= 100):
        raise InputError("expected CNT 0..100", where="FANUC CNT")
    q = np.atleast_2d(np.asarray(q_pendant_deg, dtype=float))
    if q.ndim != 2 or q.shape[1] != 6 or q.shape[0] == 0:
        raise InputError(f"expected (points, 6) joint targets, got shape {q.shape}",
                         where="FANUC targets")
    if not np.all(np.isfinite(q)):
        raise InputError("joint targets must be finite", where="FANUC targets")
    n = len(q)
    notes = [*_remarks(comments), f"{n} joint targets, deg,",
             "controller convention (J3 rel.", "to horizontal). Run in T1 at",
             "low override first."]
    body = [f"! {t} ;" for t in notes]
    for i in range(1, n + 1):
        term = "FINE" if i in (1, n) else f"CNT{cnt}"
        body.append(f"J P[{i}] {speed_percent}% {term} ;")
    stamp = datetime.datetime.now(datetime.UTC).strftime("DATE %y-%m-%d  TIME %H:%M:%S")
    lines = [
        f"/PROG  {name}",
        "/ATTR",
        "OWNER\t\t= MNEDITOR;",
        'COMMENT\t\t= "stiff campaign";',
        "PROG_SIZE\t= 0;",
        f"CREATE\t\t= {stamp};",
        f"MODIFIED\t= {stamp};",
        "FILE_NAME\t= ;",
        "VERSION\t\t= 0;",
        f"LINE_COUNT\t= {len(body)};",
        "MEMORY_SIZE\t= 0;",
        "PROTECT\t\t= READ_WRITE;",
        "TCD:  STACK_SIZE\t= 0,",
        "      TASK_PRIORITY\t= 50,",
        "      TIME_SLICE\t= 0,",
        "      BUSY_LAMP_OFF\t= 0,",
        "      ABORT_REQUEST\t= 0,",
        "      PAUSE_REQUEST\t= 0;",
        "DEFAULT_GROUP\t= 1,*,*,*,*;",
        "CONTROL_CODE\t= 00000000 00000000;",
        "/MN",
        *[f"{k:4d}:  {text}" for k, text in enumerate(body, start=1)],
        "/POS",
    ]
    for i, row in enumerate(q, start=1):
        j = [f"J{k + 1}={v:10.3f} deg" for k, v in enumerate(row)]
        lines += [f"P[{i}]{{", "   GP1:", f"\tUF : {uframe}, UT : {utool},",
                  f"\t{j[0]},\t{j[1]},\t{j[2]},", f"\t{j[3]},\t{j[4]},\t{j[5]}", "};"]
    lines += ["/END", ""]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines).replace("\n", "\r\n"))
    return path
