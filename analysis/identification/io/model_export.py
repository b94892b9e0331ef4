"""The identified model as a file every command reads, and K_X in results.json.

:func:`export_model` (called by ``campaign analyze``) writes ``model.toml``
beside ``results.json``: the robot file the run was analysed with (same
geometry, limits, conventions and zones; the run's tool composed into
``[tool]``), whose joint stiffness is the identified one, plus an
``[identification]`` table holding the covariance of the identified joint
*compliances* x = 1/k, the method, n_tests, the source run, its protocol hash
and the date (format: :mod:`analysis.model.robot_files`). Joints not
identified keep the robot file's nominal stiffness and are listed in
``joints_nominal``. It also adds ``cartesian_stiffness`` to results.json:
K_X with and without K_C at every tested pose, with standard errors, SI.
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from analysis.errors import InputError, SingularPoseError
from analysis.identification.io.measurements import TestArrays, to_arrays
from analysis.identification.result import IdentificationResult
from analysis.model.robot_model import RobotModel

_LENGTH = {"m": 1.0, "mm": 1e-3}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
_STIFF = {"N m/rad": 1.0, "kN m/rad": 1e3}


def _tool_in_flange(robot: RobotModel) -> np.ndarray:
    """Transform (4, 4) of P in the flange frame (m): the robot file's tool and any added one."""
    from analysis.model.robots import tool_in_flange

    tool = tool_in_flange(robot)
    if tool is None:
        raise InputError("the robot has no flange frame (not built from a robot file)")
    return tool


def _rpy(rot: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    return np.asarray(pin.rpy.matrixToRpy(rot), dtype=float)


def model_file_data(result: IdentificationResult, robot: RobotModel, *, source_run: str,
                    protocol_sha256: str, date: str, software: str = "") -> dict:
    """The mapping of ``model.toml`` (robot-file format) for an identification result.

    Raises :class:`InputError` when the robot was not loaded from a robot file
    (URDF) or a joint has neither an identified nor a nominal stiffness.
    """
    from analysis.file_errors import read_mapping_file

    src = robot.source_file
    if not src or Path(src).suffix.lower() not in (".toml", ".yaml", ".yml"):
        raise InputError("the robot was not loaded from a robot file (URDF?): model.toml "
                         "needs its geometry in the robot-file format", where=str(src))
    data, _ = read_mapping_file(Path(src), "robot file")
    data = dict(data)
    k = np.asarray(result.k, dtype=float)
    ident_idx = [j for j in result.joints if np.isfinite(k[j]) and k[j] > 0]
    notes = [f"k{j + 1}: the identified compliance is not positive; nominal kept"
             for j in set(result.joints) - set(ident_idx)]
    nominal_idx = [j for j in range(robot.n) if j not in ident_idx]
    data["joints"] = _joint_stiffness(data, robot, k, ident_idx, src)
    data["stiffness_unit"] = "N m/rad"
    notes += _set_tool(data, robot)
    data.pop("aliases", None)  # a model file is named by its path, never by a built-in name
    sources = dict(data.get("sources") or {})
    ident_txt = ", ".join(f"k{j + 1}" for j in ident_idx) or "none"
    nom_txt = ", ".join(f"k{j + 1}" for j in nominal_idx)
    stiff_src = f"{ident_txt} identified by campaign analyze ({result.method}) from {source_run}"
    if nominal_idx:
        stiff_src += f"; {nom_txt} nominal: {sources.get('stiffness', 'robot file')}"
    sources["stiffness"] = stiff_src
    data["sources"] = sources
    data["identification"] = {
        "quantity": "compliance",
        "covariance_unit": "(rad/(N m))^2",
        "covariance": _identified_covariance(result, robot.n, ident_idx).tolist(),
        "joints_identified": [j + 1 for j in ident_idx],
        "joints_nominal": [j + 1 for j in nominal_idx],
        "method": result.method,
        "covariance_source": result.covariance,
        "confidence": float(result.confidence),
        "n_tests": int(result.n_tests),
        "n_poses": int(result.n_poses),
        "source_run": source_run,
        "protocol_sha256": protocol_sha256,
        "date": date,
        "software": software,
        "notes": notes,
    }
    chosen = model_class_table(result)
    if chosen is not None:
        data["model_class"] = chosen
    return data


def model_class_table(result: IdentificationResult) -> dict | None:
    """``[model_class]`` (format version 2) of a result whose ``--model`` chose a class
    beyond the joint springs (link compliances SI at their distal frames, lost motion
    per joint (rad; absent: not identified), compensator law), or None."""
    sel = (result.assumptions or {}).get("model_classes") or {}
    name = sel.get("chosen")
    if not name or name == "joints":
        return None
    cand = next((c for c in sel.get("candidates", ()) if c.get("model") == name), None)
    if cand is None or "error" in cand:
        return None
    values = {p["name"]: p["value"] for p in cand.get("parameters", ())}
    table: dict = {"version": 2, "name": name,
                   "notes": [f"chosen by campaign analyze --model {sel.get('asked')}: "
                             f"{sel.get('rule')}"]}
    mats = cand.get("link_compliance") or {}
    table["links"] = [{"link": int(link), "compliance": m} for link, m in mats.items()]
    lcov = _link_covariance(cand, sel, bool(getattr(result, "misfit_accepted", False)))
    if mats and lcov is not None:
        table["link_covariance"] = lcov
    if "lost-motion" in name:
        # TOML has no null: a joint not identified is left out of notes as such
        table["lost_motion_rad"] = [float(values.get(f"2b{j}", 0.0)) for j in range(1, 7)]
        missing = [j for j in range(1, 7) if f"2b{j}" not in values]
        if missing:
            table["notes"].append("lost motion not identified (0 written) for joints "
                                  + ", ".join(str(j) for j in missing))
    if "compensator" in name:
        table["compensator"] = {k: float(v) for k, v in values.items()
                                if k in ("c1", "c2", "preload", "rate")}
        if "compensator_q2ref_rad" in cand:
            table["compensator"]["q2ref_rad"] = float(cand["compensator_q2ref_rad"])
        ccov = _compensator_covariance(cand, sel, bool(getattr(result, "misfit_accepted",
                                                               False)),
                                       table.get("link_covariance"))
        if ccov is not None:
            table["compensator_covariance"] = ccov
    return table


def _compensator_covariance(cand: dict, sel: dict, widened: bool,
                            lcov: dict | None) -> dict | None:
    """``[model_class.compensator_covariance]``: the compensator law's identified c1, c2,
    their covariance (SI), their cross-covariance with x1..x6 = 1/k (6 rows, 0 for a
    joint not fitted) and, beside link entries, with those of ``[model_class
    .link_covariance]`` (its order), from the candidate's covariance; times
    prediction_sigma_scale^2 for a result kept with --accept-misfit."""
    cov = cand.get("covariance") or {}
    names = list(cov.get("parameters") or ())
    law = [i for i, n in enumerate(names) if n in ("c1", "c2")]
    if not law:
        return None
    M = np.asarray(cov["matrix"], dtype=float)
    s2 = (float(sel.get("prediction_sigma_scale") or 1.0) if widened else 1.0) ** 2
    cross = np.zeros((6, len(law)))
    for i, n in enumerate(names):
        if n.startswith("x"):
            cross[int(n[1:]) - 1] = M[i, law]
    out = {"parameters": [names[i] for i in law],
           "matrix": (s2 * M[np.ix_(law, law)]).tolist(),
           "joint_cross": (s2 * cross).tolist()}
    if lcov is not None:
        rows = [names.index(n) for n in lcov["parameters"]]
        out["link_cross"] = (s2 * M[np.ix_(rows, law)]).tolist()
    return out


def _link_covariance(cand: dict, sel: dict, widened: bool) -> dict | None:
    """``[model_class.link_covariance]``: the kept link entries' names, their covariance
    (SI) and their cross-covariance with the joint compliances x1..x6 (6 rows, 0 for a
    joint not fitted), from the candidate's covariance; times prediction_sigma_scale^2
    for a result kept with --accept-misfit (as the joints' covariance)."""
    cov = cand.get("covariance") or {}
    names = list(cov.get("parameters") or ())
    links = [i for i, n in enumerate(names) if n.startswith("C")]
    if not links:
        return None
    M = np.asarray(cov["matrix"], dtype=float)
    s = float(sel.get("prediction_sigma_scale") or 1.0) if widened else 1.0
    cross = np.zeros((6, len(links)))
    for i, n in enumerate(names):
        if n.startswith("x"):
            cross[int(n[1:]) - 1] = M[i, links]
    return {"parameters": [names[i] for i in links],
            "matrix": (s**2 * M[np.ix_(links, links)]).tolist(),
            "joint_cross": (s**2 * cross).tolist()}


def _identified_covariance(result: IdentificationResult, n: int, ident_idx) -> np.ndarray:
    """(n, n) covariance of the compliances ((rad/(N m))^2) of the joints ``ident_idx``
    (identified with a positive k), zero for the others."""
    cov = np.zeros((n, n))
    cols = list(result.joints)
    for a, ja in enumerate(cols):
        for b, jb in enumerate(cols):
            if ja in ident_idx and jb in ident_idx:
                cov[ja, jb] = result.cov_x[a, b]
    return cov


def _joint_stiffness(data: dict, robot: RobotModel, k: np.ndarray, ident_idx, src) -> list:
    """The robot file's joints with each stiffness (N m/rad): the identified k where
    ``ident_idx``, else the file's nominal one; refused when a joint has neither."""
    joints = [dict(j) for j in data["joints"]]
    old_unit = _STIFF[data.get("stiffness_unit", "N m/rad")]
    for j in range(robot.n):
        if j in ident_idx:
            joints[j]["stiffness"] = float(k[j])
        elif joints[j].get("stiffness") is not None:
            joints[j]["stiffness"] = float(joints[j]["stiffness"]) * old_unit
        else:
            raise InputError(f"k{j + 1} was not identified and {robot.name} has no nominal "
                             "value for it: model.toml needs every joint's stiffness "
                             "(identify all joints, or add the nominal one to the robot file)",
                             where=src)
    return joints


def _set_tool(data: dict, robot: RobotModel) -> list[str]:
    """Write the run's tool (in the file's length and angle units) into ``data["tool"]``;
    the note when it moved the file's tool point (its reference poses are then dropped)."""
    ls, ang = _LENGTH[data["length_unit"]], _ANGLE[data["angle_unit"]]
    tool = _tool_in_flange(robot)
    old_tool = data.get("tool") or {}
    xyz = [float(v) for v in tool[:3, 3] / ls]
    rpy = [float(v) for v in _rpy(tool[:3, :3]) / ang]
    moved = not (np.allclose(xyz, old_tool.get("xyz", [0, 0, 0]), atol=1e-9)
                 and np.allclose(rpy, old_tool.get("rpy", [0, 0, 0]), atol=1e-9))
    data["tool"] = {"xyz": xyz, "rpy": rpy}
    if not moved:
        return []
    # published FK checks are of the file's own tool point
    data.pop("reference_poses", None)
    return ["tool of the run composed into [tool]; reference_poses dropped"]


def write_model_file(data: dict, path: Path) -> Path:
    """Write ``data`` as TOML with a header saying what the file is."""
    import tomli_w

    header = ("# Identified robot model written by `campaign analyze`: a robot file "
              "(analysis/model/robot_files.py)\n# whose joint stiffness is the identified "
              "one; [identification] holds the covariance of the\n# identified compliances "
              "x = 1/k. Use it with any --robot option.\n")
    from analysis.output_files import write_text

    write_text(path, header + tomli_w.dumps(data))
    return path


#: K_X is listed at most at this many distinct tested poses (a 1e6-row import would
#: otherwise write ~1e6 entries of 6 x 6 matrices into results.json)
POSES_LISTED = 200


def _first_of_groups(group: np.ndarray) -> np.ndarray:
    """Index of the first element of each distinct value of ``group`` (integer labels), by
    increasing value: ``np.unique(group, return_index=True)[1]`` without its sorted copy
    and permutation of the whole array (~40 MB at 1e6 tests, the peak of a large import)."""
    group = np.asarray(group)
    if group.size == 0 or group.dtype.kind not in "iu" or group.min() < 0 \
            or group.max() >= 4 * group.size:
        return np.unique(group, return_index=True)[1]
    first = np.full(int(group.max()) + 1, group.size, dtype=np.int64)
    for s in range(0, group.size, 1 << 16):  # indices a block at a time
        part = group[s:s + (1 << 16)]
        np.minimum.at(first, part, np.arange(s, s + part.size, dtype=np.int64))
    return first[first < group.size]


def cartesian_stiffness_at_tests(result: IdentificationResult, robot: RobotModel,
                                 tests: TestArrays) -> dict:
    """K_X with and without K_C, standard errors and principal stiffnesses at the tested poses.

    One entry per distinct tested pose (joint angles equal to within the
    encoder noise, :mod:`analysis.identification.poses`), at most
    :data:`POSES_LISTED` in order of appearance, with the wrench of its first
    test (K_C depends on the wrench). Joints not identified take the nominal
    stiffness (rigid without one) and contribute no uncertainty.
    """
    from analysis.identification.prediction_stiffness import stiffness_for_prediction
    from analysis.kinetostatics.stiffness import (
        cartesian_stiffness,
        complementary_stiffness_from_jacobian,
    )
    from analysis.kinetostatics.uncertainty import (
        cartesian_stiffness_se,
        principal_stiffness,
        stiffness_covariance,
    )
    from analysis.model.kinematics import jacobian

    k, notes = stiffness_for_prediction(result.k, robot.nominal_stiffness)
    cov_x = np.zeros((robot.n, robot.n))
    cols = list(result.joints)
    cov_x[np.ix_(cols, cols)] = result.cov_x
    finite = np.isfinite(result.k)
    cov_x[~finite, :] = 0.0
    cov_x[:, ~finite] = 0.0
    cov_k = stiffness_covariance(k, cov_x)
    from analysis.identification.poses import pose_groups, pose_tolerance

    group = result.pose_group
    if group is None or len(group) != tests.m:
        group = pose_groups(tests.q, pose_tolerance(result.noise))
    first = _first_of_groups(group)  # groups are numbered by appearance
    listed = first[:POSES_LISTED]
    poses = []
    for i in listed:
        q, w = tests.q[i], tests.w[i]
        J = jacobian(robot, q)
        K_C = complementary_stiffness_from_jacobian(J, w)
        try:
            K_X, K_0 = cartesian_stiffness(J, k, K_C), cartesian_stiffness(J, k)
        except SingularPoseError:
            poses.append({"pose": str(tests.pose[i]), "singular": True})
            continue
        se = cartesian_stiffness_se(J, cov_k)
        pt, pr = principal_stiffness(K_X)
        poses.append({
            "pose": str(tests.pose[i]), "line": int(tests.line[i]), "q_rad": q.tolist(),
            "wrench_N_Nm": w.tolist(), "K_X": K_X.tolist(), "K_X_se": se.tolist(),
            "K_X_without_K_C": K_0.tolist(), "K_X_without_K_C_se": se.tolist(),
            "principal_translational_N_per_m": pt.tolist(),
            "principal_rotational_Nm_per_rad": pr.tolist(),
        })
    return {
        "poses": poses,
        "poses_listed": (f"all {len(first)} distinct poses" if len(first) == len(listed) else
                         f"the first {len(listed)} of {len(first)} distinct poses"),
        "joint_stiffness_Nm_per_rad": k.tolist(),
        "notes": notes,
        "method": "K_X = J^-T (K_theta - K_C) J^-1 (eq. 6) and without K_C (eq. 12), at P, "
                  "base frame, wrench of the pose's first test; K_X is linear in k, so its "
                  "standard errors are exact given cov(k), which comes from the covariance of "
                  "the compliances by the delta method (same errors with and without K_C). "
                  "Principal stiffnesses: inverses of the eigenvalues of the translational "
                  "(rotational) block of K_X^-1, i.e. under a pure force (moment).",
        "units": {"K_X": "N/m | N/rad ; N | N m/rad blocks (rows/columns: dx dy dz rx ry rz)",
                  "q_rad": "rad, model convention", "wrench_N_Nm": "N, N m at P, base frame"},
    }


def export_model(result: IdentificationResult, robot: RobotModel, out_dir: str | Path,
                 table, info) -> dict[str, Path]:
    """Write ``model.toml`` and add K_X to ``results.json`` in ``out_dir`` (written before).

    ``table`` is the tests table analysed; ``info`` the campaign summary: any
    record with ``location`` (the source run), ``protocol_sha256`` and ``software``,
    such as the report's ``CampaignInfo`` (read by attribute, nothing imported).
    When no model file can be written (URDF robot, a joint without
    any stiffness), results.json says why under ``model_file_note``.
    """
    out = Path(out_dir)
    tests = table if isinstance(table, TestArrays) else to_arrays(table)
    results_path = out / "results.json"
    doc = json.loads(results_path.read_text())
    doc["cartesian_stiffness"] = cartesian_stiffness_at_tests(result, robot, tests)
    date = datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    paths: dict[str, Path] = {}
    try:
        software = ", ".join(f"{k} {v}" for k, v in (info.software or {}).items())
        data = model_file_data(result, robot, source_run=str(info.location),
                               protocol_sha256=str(info.protocol_sha256), date=date,
                               software=software)
        paths["model"] = write_model_file(data, out / "model.toml")
        doc["model_file"] = "model.toml"
    except InputError as err:
        doc["model_file"] = None
        doc["model_file_note"] = f"no model.toml: {err}"
    from analysis.output_files import write_text

    write_text(results_path, json.dumps(doc, indent=2) + "\n")
    return paths
