"""Robot programs that replay a list of joint targets: KUKA KRL and Universal Robots URScript
(ABB RAPID in :mod:`analysis.export.rapid_program`, FANUC ``.LS`` in
:mod:`analysis.export.fanuc_tp`; :func:`write_program` picks one).

Joint targets are given in the controller's (teach pendant) convention, as the
controller takes them: degrees for KRL (``E6AXIS`` A1..A6), radians for
URScript (``movej``). Both programs move joint-interpolated (PTP / movej)
through every target: a Cartesian LIN would be re-planned by the controller
from its own rigid kinematics and lose the computed joint values. Programs
are written for a dry run first (reduced speed, see the header of each file).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.output_files import make_dir, write_text

_KRL_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,23}$")


def check_targets(q: np.ndarray, where: str) -> np.ndarray:
    """``q`` as a (points, 6) array of finite joint targets, else an InputError at ``where``."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.ndim != 2 or q.shape[1] != 6 or q.shape[0] == 0:
        raise InputError(f"expected (points, 6) joint targets, got shape {q.shape}", where=where)
    if not np.all(np.isfinite(q)):
        raise InputError("joint targets must be finite", where=where)
    return q


def _comments(lines, mark: str) -> list[str]:
    return [f"{mark} {line}".rstrip() for text in lines for line in str(text).splitlines()]


def write_krl(directory: str | Path, name: str, q_pendant_deg: np.ndarray,
              comments: list[str] | tuple[str, ...] = (), velocity_percent: float = 10.0
              ) -> tuple[Path, Path]:
    """Write ``NAME.src`` and ``NAME.dat`` moving PTP through joint targets A1..A6 (deg).

    The first point is reached with an exact stop, the others with C_PTP
    approximation; ``velocity_percent`` sets BAS(#VEL_PTP). Returns (src, dat).
    """
    if not _KRL_NAME.match(name):
        raise InputError(f"{name!r} is not a KRL name (letter first, then letters, digits "
                         "or _, at most 24 characters)", where="program name")
    if not 0 < velocity_percent <= 100:
        raise InputError("expected 0 < velocity <= 100 %", where="velocity_percent")
    q = check_targets(q_pendant_deg, "KRL targets")
    out = make_dir(directory)
    n = len(q)
    upper = name.upper()
    src = [
        "&ACCESS RVP", "&REL 1", f"DEF {upper}( )",
        *_comments(comments, ";"),
        f"; {n} joint targets (A1..A6 in deg, pendant convention) in {upper}.dat.",
        "; Run it first in T1 at reduced speed.",
        "DECL INT I", "", "BAS(#INITMOV, 0)", f"BAS(#VEL_PTP, {velocity_percent:g})",
        "PTP XPATH[1]",
        f"FOR I = 2 TO {n}",
        "   PTP XPATH[I] C_PTP",
        "ENDFOR",
        "END", "",
    ]
    dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {upper}", f"DECL E6AXIS XPATH[{n}]"]
    for i, row in enumerate(q, start=1):
        axes = ",".join(f"A{j + 1} {v:.6f}" for j, v in enumerate(row))
        dat.append(f"XPATH[{i}]={{{axes},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}")
    dat += ["ENDDAT", ""]
    src_path, dat_path = out / f"{name}.src", out / f"{name}.dat"
    write_text(src_path, "\n".join(src).replace("\n", "\r\n"))
    write_text(dat_path, "\n".join(dat).replace("\n", "\r\n"))
    return src_path, dat_path


def write_urscript(path: str | Path, name: str, q_rad: np.ndarray,
                   comments: list[str] | tuple[str, ...] = (), speed_rad_s: float = 0.25,
                   acceleration_rad_s2: float = 0.5, blend_m: float = 0.0) -> Path:
    """Write a URScript program ``def NAME():`` with one movej per joint target (rad).

    ``blend_m`` is the blend radius (m) between targets (0: stop at each).
    """
    if not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", name):
        raise InputError(f"{name!r} is not a URScript function name", where="program name")
    for value, what in ((speed_rad_s, "speed"), (acceleration_rad_s2, "acceleration")):
        if not value > 0:
            raise InputError(f"expected a positive {what}", where=f"URScript {what}")
    q = check_targets(q_rad, "URScript targets")
    lines = [f"def {name}():", *("  " + c for c in _comments(comments, "#")),
             f"  # {len(q)} joint targets (rad, controller convention); check at low speed first"]
    for row in q:
        joints = ", ".join(f"{v:.9f}" for v in row)
        lines.append(f"  movej([{joints}], a={acceleration_rad_s2:g}, v={speed_rad_s:g}, "
                     f"r={blend_m:g})")
    lines += ["end", f"{name}()", ""]
    path = Path(path)
    make_dir(path.parent)
    write_text(path, "\n".join(lines))
    return path


#: program formats and the brand they are written for by default
FORMATS = ("krl", "urscript", "rapid", "fanuc-ls")


def default_format(robot_name: str, key: str = "") -> str | None:
    """The program format of a robot by its model name or key, or None."""
    name, key = robot_name.lower(), key.lower()
    if "kuka" in name or key.startswith("kr"):
        return "krl"
    if "universal robots" in name or key.startswith("ur"):
        return "urscript"
    if name.startswith("abb") or "irb" in name:
        return "rapid"
    if "fanuc" in name:
        return "fanuc-ls"
    return None


def write_program(kind: str, directory: str | Path, name: str, q_ctrl: np.ndarray,
                  comments: list[str] | tuple[str, ...] = ()) -> list[Path]:
    """Write joint targets ``q_ctrl`` (rad, controller convention) as a ``kind`` program."""
    directory = Path(directory)
    if kind == "krl":
        return list(write_krl(directory, name, np.degrees(q_ctrl), comments))
    if kind == "urscript":
        return [write_urscript(directory / f"{name}.script", name, q_ctrl, comments)]
    if kind == "rapid":
        from analysis.export.rapid_program import write_rapid

        return [write_rapid(directory / f"{name}.mod", name, np.degrees(q_ctrl), comments)]
    if kind == "fanuc-ls":
        from analysis.export.fanuc_tp import write_fanuc_ls

        return [write_fanuc_ls(directory / f"{name.upper()}.LS", name, np.degrees(q_ctrl),
                               comments)]
    raise InputError(f"unknown program format {kind!r}; known: {', '.join(FORMATS)}",
                     where="--program")
