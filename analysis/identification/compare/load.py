"""Read one campaign for ``campaign compare``: results.json and the model.toml beside it.

Every field used is checked before any number is computed; a damaged file (not UTF-8,
not JSON or TOML, a field of the wrong type, size or range) is refused with one
:class:`InputError` naming the file and the field.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError

#: joints per results.json entry list (``joint_stiffness_Nm_per_rad`` has one per joint)
N_JOINTS = 6


@dataclass
class Campaign:
    """One identification as read from results.json (SI).

    k, x (n,) stiffness (N m/rad, NaN if not identified) and compliance (rad/(N m));
    cov_x (n, n) compliance covariance ((rad/(N m))^2, zero for joints not identified);
    joints : 0-based identified joints; model : model.toml beside it (mapping) or None;
    tests_data : results.json ``tests_data`` (:mod:`analysis.identification.io.data_fingerprint`),
    None when the file predates it; method : the estimator named in results.json, with its
    robust mode when there is one, e.g. "exact, huber" (None when absent); accepted : the
    result was kept despite a refusal (``misfit_accepted``).
    """

    source: str
    robot: str
    k: np.ndarray
    x: np.ndarray
    cov_x: np.ndarray
    joints: tuple[int, ...]
    model: dict | None = None
    tests_data: dict | None = None
    method: str | None = None
    accepted: bool = False


def _results_path(path: Path) -> Path:
    if path.is_file():
        return path
    for cand in (path / "results.json", path / "analysis" / "results.json"):
        if cand.is_file():
            return cand
    raise InputError("no results.json here (expected a run directory, its analysis "
                     "directory, or a results.json file)", where=str(path))


def read_text_utf8(path: Path) -> str:
    """The file's text; refuses a file that is not UTF-8 (naming UTF-16 when it is)."""
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror or err}", where=str(path)) from None
    wide = len(raw) >= 4 and ((raw[1] == 0 and raw[3] == 0) or (raw[0] == 0 and raw[2] == 0))
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff") or wide:  # a BOM, or ASCII text as UTF-16
        raise InputError("the file is UTF-16 (or another wide encoding): save it as UTF-8",
                         where=str(path))
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(f"not UTF-8 text (byte 0x{raw[err.start]:02x} at offset "
                         f"{err.start}): save it as UTF-8", where=str(path)) from None


def _number(value, field: str, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{field}: expected a number, got {value!r}"[:200], where=where)
    return float(value)


def _stiffness(doc: dict, where: str) -> np.ndarray:
    field = "joint_stiffness_Nm_per_rad"
    values = doc.get(field)
    if not isinstance(values, list):
        raise InputError(f"{field}: expected a list of {N_JOINTS} numbers (null for a joint "
                         "not identified)", where=where)
    if len(values) != N_JOINTS:
        raise InputError(f"{field}: {len(values)} entries, expected {N_JOINTS} (one per joint)",
                         where=where)
    return np.array([np.nan if v is None else _number(v, f"{field}[{i}]", where)
                     for i, v in enumerate(values)])


def _joints(doc: dict, where: str) -> tuple[int, ...]:
    field = "joints_identified"
    values = doc.get(field)
    if not isinstance(values, list) or not values:
        raise InputError(f"{field}: expected a non-empty list of joint numbers 1..{N_JOINTS}",
                         where=where)
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= N_JOINTS:
            raise InputError(f"{field}: {v!r} is not a joint number 1..{N_JOINTS}"[:200],
                             where=where)
        out.append(v - 1)
    if len(set(out)) != len(out):
        raise InputError(f"{field}: a joint is listed twice", where=where)
    return tuple(out)


def _covariance(doc: dict, p: int, where: str) -> np.ndarray:
    field = "covariance_of_compliance"
    rows = doc.get(field)
    if not (isinstance(rows, list) and len(rows) == p
            and all(isinstance(r, list) and len(r) == p for r in rows)):
        raise InputError(f"{field}: expected a {p} x {p} matrix (one row and column per joint "
                         "of joints_identified)", where=where)
    cov = np.array([[_number(v, f"{field}[{i}][{j}]", where) for j, v in enumerate(r)]
                    for i, r in enumerate(rows)])
    if not np.all(np.isfinite(cov)):
        raise InputError(f"{field}: not finite", where=where)
    bad = [i for i in range(p) if not cov[i, i] > 0]
    if bad:
        raise InputError(f"{field}[{bad[0]}][{bad[0]}]: a variance of {cov[bad[0], bad[0]]:g} "
                         "(expected > 0): no usable estimate or variance", where=where)
    scale = float(np.max(np.abs(np.diag(cov)))) if p else 0.0
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-12 * scale):
        raise InputError(f"{field}: not symmetric", where=where)
    return cov


def _tests_data(doc: dict, where: str) -> dict | None:
    data = doc.get("tests_data")
    if data is None:
        return None
    digests = data.get("row_digests") if isinstance(data, dict) else None
    if not (isinstance(data, dict) and isinstance(data.get("sha256"), str)
            and isinstance(digests, list) and all(isinstance(v, str) for v in digests)):
        raise InputError("tests_data: expected sha256 (text) and row_digests (list of text)",
                         where=where)
    return data


def _model(path: Path) -> dict | None:
    """model.toml beside results.json (mapping) or None; refuses a damaged one."""
    import tomllib

    if not path.is_file():
        return None
    try:
        model = tomllib.loads(read_text_utf8(path))
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"not a TOML file: {err}", where=str(path)) from None
    joints = model.get("joints", [])
    if not (isinstance(joints, list) and all(isinstance(j, dict) for j in joints)):
        raise InputError("joints: expected an array of tables ([[joints]])", where=str(path))
    return model


def load_campaign(path: str | Path) -> Campaign:
    """Read a run directory, an analysis directory or a results.json file."""
    rp = _results_path(Path(path))
    where = str(rp)
    try:
        doc = json.loads(read_text_utf8(rp))
    except json.JSONDecodeError as err:
        raise InputError(f"not JSON: {err}", where=where) from None
    if not isinstance(doc, dict):
        raise InputError("not a results.json of campaign analyze (expected a JSON object)",
                         where=where)
    robot = doc.get("robot")
    if not isinstance(robot, str) or not robot:
        raise InputError("robot: expected the robot's name (text)", where=where)
    k = _stiffness(doc, where)
    joints = _joints(doc, where)
    cov_p = _covariance(doc, len(joints), where)
    for j in joints:
        if not (math.isfinite(k[j]) and k[j] > 0):
            raise InputError(f"joint_stiffness_Nm_per_rad[{j}]: joint {j + 1} is in "
                             f"joints_identified but its stiffness is {k[j]:g} (expected a "
                             "positive number)", where=where)
    n = len(k)
    cov = np.zeros((n, n))
    cov[np.ix_(joints, joints)] = cov_p
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(np.isfinite(k) & (k > 0), 1.0 / k, np.nan)
    method = doc.get("method")
    robust = doc.get("robust")
    if isinstance(method, str) and isinstance(robust, dict) and isinstance(
            robust.get("method"), str):
        method = f"{method}, {robust['method']}"
    accepted = doc.get("misfit_accepted")
    return Campaign(where, robot, k, x, cov, joints, _model(rp.parent / "model.toml"),
                    _tests_data(doc, where), method if isinstance(method, str) else None,
                    isinstance(accepted, dict) and accepted.get("accepted") is True)
