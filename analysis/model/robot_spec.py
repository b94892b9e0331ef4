"""The text naming a robot (``--robot``, ``[campaign] robot``, the GUI's pickers).

A built-in name, a robot file (``.toml``/``.yaml``/``.yml``), or a URDF with its tool
frame written after a ``#``: ``arm.urdf#tool0`` (the same as ``--robot arm.urdf --tip
tool0``), so that one string names a URDF robot wherever a robot is named. Kept free of
heavy imports: the protocol reader uses it.
"""

from __future__ import annotations

ROBOT_FILE_SUFFIXES = (".toml", ".yaml", ".yml", ".urdf")


def split_urdf_spec(spec: str) -> tuple[str, str | None]:
    """``FILE.urdf#FRAME`` -> (``FILE.urdf``, ``FRAME``); any other text -> (text, None)."""
    head, sep, frame = spec.rpartition("#")
    if sep and frame.strip() and head.lower().endswith(".urdf"):
        return head, frame.strip()
    return spec, None


def is_robot_file(spec: str) -> bool:
    """The spec names a file (robot file or URDF, with or without ``#FRAME``)."""
    return split_urdf_spec(spec.strip())[0].lower().endswith(ROBOT_FILE_SUFFIXES)
