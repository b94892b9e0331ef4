"""The protocols shipped with the package: ``campaign/protocols/*.toml`` as package data.

They are found through :mod:`importlib.resources`, so an installed wheel finds
its own copies wherever it was installed, and a source checkout (or an editable
install) finds the repository's; the repository's ``protocols/`` is a link to
the same folder. A protocol is named by its file's stem (``kr240-2``).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from analysis.errors import InputError

#: the package folder holding the shipped protocols
PACKAGE = "campaign"
FOLDER = "protocols"


def shipped_folder() -> Path:
    """The folder of the shipped protocols in the installed package (a real directory)."""
    folder = resources.files(PACKAGE) / FOLDER
    path = Path(str(folder))
    if not path.is_dir():
        raise InputError("the shipped protocols are missing from this installation "
                         "(package data campaign/protocols/*.toml)", where=str(path))
    return path


def shipped_protocols() -> dict[str, Path]:
    """{name: file} of every shipped protocol, sorted by name."""
    folder = shipped_folder()
    return {p.stem: p for p in sorted(folder.glob("*.toml")) if p.is_file()}


def shipped_protocol(name: str) -> Path:
    """The file of the shipped protocol ``name`` (``kr240-2``); refuse an unknown name."""
    found = shipped_protocols()
    if name not in found:
        raise InputError(f"no shipped protocol {name!r}; shipped: {', '.join(found) or 'none'}",
                         where="protocol")
    return found[name]
