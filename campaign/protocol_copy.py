"""A protocol's copy in a plan or run directory, with its robot file beside it.

A robot file or URDF named by a relative path in ``[campaign] robot`` is read relative to
the protocol file. The plan directory's copy (``plans/NAME/protocol.toml``) and the run
directory's (``runs/NAME/protocol.toml``) sit elsewhere, so the path would point at nothing
(or at another file). The copy therefore names the robot file by its bare name and the
robot file is copied beside it: a plan or run directory reads the robot it was made with,
wherever it is moved, and editing the workspace's robot file later does not change it.
Built-in robots and absolute paths are copied as written.
"""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

from analysis.errors import InputError
from analysis.model.robot_spec import is_robot_file, split_urdf_spec
from analysis.model.robots import builtin_files


def _parsed_robot(text: str, suffix: str) -> object:
    """``[campaign] robot`` of a protocol text (None if it does not parse)."""
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            doc = yaml.safe_load(text)
        else:
            doc = tomllib.loads(text)
        return doc["campaign"]["robot"]
    except Exception:  # noqa: BLE001 - any unreadable text: no rewrite
        return None


def portable_copy(protocol) -> tuple[str, dict[str, Path]]:
    """The text of the protocol's copy and the files to write beside it.

    Returns (text, {file name in the directory: source path}). With a relative robot path
    the text's ``robot`` value becomes the file's bare name (``robots/arm.urdf#tool0`` ->
    ``arm.urdf#tool0``; a file called ``protocol.*`` is renamed ``robot-protocol.*``), the
    rest of the text verbatim. Otherwise the text as read and no file.
    """
    text = protocol.text
    spec = protocol.campaign.robot
    if spec.strip().lower() in builtin_files() or not is_robot_file(spec.strip()):
        return text, {}
    head, frame = split_urdf_spec(spec.strip())
    rel = Path(head)
    source = Path(protocol.path).parent / rel
    if rel.is_absolute() or not source.is_file():
        return text, {}  # absolute: found from anywhere; missing: the loader says so
    name = rel.name if not rel.name.lower().startswith("protocol.") else f"robot-{rel.name}"
    new_spec = name + (f"#{frame}" if frame else "")
    if new_spec != spec:
        suffix = Path(protocol.path).suffix.lower()
        value = re.compile(r"^(\s*robot\s*[=:]\s*)([\"']?)" + re.escape(spec) + r"\2",
                           re.MULTILINE)
        rewritten, n = value.subn(lambda m: m.group(1) + m.group(2) + new_spec + m.group(2),
                                  text)
        if n != 1 or _parsed_robot(rewritten, suffix) != new_spec:
            raise InputError(f"cannot rewrite robot = {spec!r} for the protocol's copy; "
                             "give the robot file's absolute path",
                             where=protocol.where("campaign", "robot"))
        text = rewritten
    return text, {name: source}


def copy_beside(files: dict[str, Path], directory: Path) -> None:
    """Copy each source file to ``directory/NAME`` (the robot file of :func:`portable_copy`)."""
    for name, source in files.items():
        target = Path(directory) / name
        if target.resolve() == Path(source).resolve():
            continue
        try:
            shutil.copyfile(source, target)
        except OSError as err:
            raise InputError(f"cannot copy the robot file {source} here: {err.strerror}",
                             where=str(target)) from None
