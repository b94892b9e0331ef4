"""Built-in robot models and the one function that resolves ``--robot``.

Built-in models are robot files shipped in ``analysis/data/robots`` (the same
format users write, see :mod:`analysis.model.robot_files`), each number with its source.
"""

from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin

from analysis.errors import InputError
from analysis.model.robot_files import load_robot_file, load_urdf
from analysis.model.robot_model import Chain, RobotModel


def _data_dir() -> Path:
    return Path(str(resources.files("analysis") / "data" / "robots"))


def builtin_files() -> dict[str, Path]:
    """Map of every accepted built-in name (key and aliases, lower case) to its file (read
    each call: ~10 ms, no module-level cache)."""
    import tomllib

    names: dict[str, Path] = {}
    for path in sorted(_data_dir().glob("*.toml")):
        names[path.stem] = path
        with path.open("rb") as fh:
            for alias in tomllib.load(fh).get("aliases", []):
                names[alias.lower()] = path
    return names


def builtin_names() -> list[str]:
    """Canonical keys of the built-in models."""
    return sorted(p.stem for p in _data_dir().glob("*.toml"))


def _load_builtin(key: str) -> RobotModel:
    """A new :class:`RobotModel` of the built-in ``key`` (~20 ms; each caller its own, so
    that none sees another's changes)."""
    path = builtin_files()[key]
    return load_robot_file(path, key=path.stem)


def known_names_text() -> str:
    """'fanuc-s420f (also s420f, s-420f), kr240-2 (also kr240, kuka-kr240-2), ...'."""
    by_key: dict[str, list[str]] = {key: [] for key in builtin_names()}
    for name, path in builtin_files().items():
        if name != path.stem:
            by_key[path.stem].append(name)
    return ", ".join(key + (f" (also {', '.join(sorted(a))})" if a else "")
                     for key, a in by_key.items())


def closest_name(spec: str) -> str | None:
    """The built-in key whose name or alias is closest to ``spec``, if any is close."""
    import difflib

    files = builtin_files()
    match = difflib.get_close_matches(spec.strip().lower(), list(files), n=1, cutoff=0.6)
    return files[match[0]].stem if match else None


def load_robot(spec: str, tip: str | None = None, where: str = "--robot") -> RobotModel:
    """Resolve a robot: a built-in name, a robot file (.toml/.yaml/.yml) or a URDF.

    Parameters
    ----------
    spec : built-in name (see ``campaign robots``) or a file path; a URDF may name its
        tool frame as ``FILE.urdf#FRAME`` (:mod:`analysis.model.robot_spec`).
    tip : frame name of the tool point, required for a URDF (unless given with ``#``).
    where : the option or argument ``spec`` came from, for messages.
    """
    from analysis.model.robot_spec import split_urdf_spec

    key = spec.strip().lower()
    if key in builtin_files():
        return _load_builtin(key)
    spec, frame = split_urdf_spec(spec)
    if frame is not None:
        if tip and tip != frame:
            raise InputError(f"two tool frames: {frame!r} after '#' and {tip!r} (--tip); "
                             "give one", where=where)
        tip = frame
    path = Path(spec)
    if path.suffix.lower() == ".urdf":
        if not tip:
            raise InputError("a URDF needs the tool frame: add --tip FRAME (or write "
                             "FILE.urdf#FRAME)", where=where)
        return load_urdf(path, tip)
    if path.suffix.lower() in (".toml", ".yaml", ".yml"):
        if not path.is_file():
            raise InputError("robot file not found", where=str(path))
        return load_robot_file(path)
    close = closest_name(spec)
    raise InputError(
        f"unknown robot {spec!r}"
        + (f" (did you mean {close}?)" if close else "")
        + f": expected a built-in name, {known_names_text()}, or a .toml/.yaml robot "
        "file, or a .urdf with --tip",
        where=where,
    )


def tool_in_flange(robot: RobotModel) -> np.ndarray | None:
    """Transform (4, 4) of P in the flange frame (m), or None without a ``flange`` frame.

    The robot file's ``[tool]`` and any tool added by :func:`with_tool`.
    """
    model = robot.model
    if not model.existFrame("flange"):
        return None
    flange = model.frames[model.getFrameId("flange")].placement
    return (flange.inverse() * model.frames[robot.tip_frame].placement).homogeneous


def tool_mm_deg(tool: np.ndarray, digits: int = 9) -> tuple[list[float], list[float]]:
    """(xyz in mm, roll-pitch-yaw in deg) of a tool transform (4, 4) (m), rounded to ``digits``
    (no -0.0): the units a tool point is written in ([tool], --tool-xyz-mm/--tool-rpy-deg)."""
    xyz = np.round(tool[:3, 3] * 1e3, digits) + 0.0
    rpy = np.round(np.degrees(pin.rpy.matrixToRpy(tool[:3, :3])), digits) + 0.0
    return xyz.tolist(), rpy.tolist()


def with_tool(robot: RobotModel, xyz: np.ndarray, rpy: np.ndarray) -> RobotModel:
    """Copy of ``robot`` whose point P is moved by the tool (xyz in m, rpy in rad, flange frame).

    Refused when P is already away from the flange (a robot file with its own
    ``[tool]``, e.g. a ``model.toml`` written by ``campaign analyze``): both
    tools are given in the flange frame, and composing them would put P at
    neither. Refused too for an identified model (``[identification]``) whose P
    is the flange: its P is the run's tool point (docs/use.md), and another one
    must be written into its ``[tool]``, not added on the command line.
    """
    if not np.any(xyz) and not np.any(rpy):
        return robot
    tool = pin.SE3(pin.rpy.rpyToMatrix(*map(float, rpy)), np.asarray(xyz, dtype=float))
    present = tool_in_flange(robot)
    if present is not None and np.allclose(present, tool.homogeneous, atol=1e-9):
        return robot  # the same tool point given again: P is already there
    if present is not None and not np.allclose(present, np.eye(4), atol=1e-12):
        had_xyz, had_rpy = tool_mm_deg(present, 6)
        new_xyz, new_rpy = tool_mm_deg(tool.homogeneous, 6)
        raise InputError(
            f"the robot file already places P with its [tool] (xyz {had_xyz} mm, rpy "
            f"{had_rpy} deg from the flange); a second tool point (xyz {new_xyz} mm, rpy "
            f"{new_rpy} deg) would be composed on it. Give the tool point once: drop the tool "
            "option or the protocol's [tool], or write your tool into the robot file's [tool]",
            where=robot.source_file or robot.name)
    if robot.identification is not None:
        new_xyz, new_rpy = tool_mm_deg(tool.homogeneous, 6)
        raise InputError(
            "this identified model (model.toml) has P at the flange, the tool point of the "
            f"run it was identified from; a second tool point (xyz {new_xyz} mm, rpy "
            f"{new_rpy} deg) is refused: drop the tool option or the protocol's [tool], or "
            "write your tool into the file's [tool]", where=robot.source_file or robot.name)
    model = pin.Model(robot.model)
    flange = model.frames[robot.tip_frame]
    frame = pin.Frame(
        "tool_P", flange.parentJoint, robot.tip_frame, flange.placement * tool,
        pin.FrameType.OP_FRAME,
    )
    tip = model.addFrame(frame)
    chain = Chain(robot.chain.placements, robot.chain.axes, robot.chain.tip @ tool.homogeneous)
    return dataclasses.replace(robot, model=model, tip_frame=tip, chain=chain)
