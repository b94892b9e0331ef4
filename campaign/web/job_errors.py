"""A job's refusal as the web API gives it: status, the one line, and what it names.

The jobs' messages are the command line's (``add --force to overwrite its
files``): the command line prints them as they are. The API answers
``{"detail": line, "field": F, "options": {"--force": "force", ...}}``: ``field``
is the request field at fault (from the error's ``where``), ``options`` maps
each command-line option the line names to the request field it is, so that a
page can say it in its own terms (the label of its checkbox for ``force``)
while the API's ``detail`` stays the command line's line, the same for both
faces. Status: 400 bad input, 409 a refused write (disk full, permissions). A result the
data do not support (:class:`~analysis.errors.Refused`) adds ``refused``: its reasons,
``[{"text": ...}, ...]``, read from the exception, not from its message.
"""

from __future__ import annotations

import dataclasses
import errno
import re
from pathlib import Path
from typing import Any

from analysis.errors import InputError, Refused

OPTION = re.compile(r"--[a-z][a-z0-9]*(?:-[a-zA-Z0-9]+)*")
#: unit suffixes of command-line options that the SI records drop or rename
UNIT_SUFFIXES = ("_um", "_urad", "_mm", "_deg", "_pct", "_percent")


def option_field(option: str, names: list[str]) -> str | None:
    """The request field a command-line option sets, among ``names``; None if none.

    ``--force`` -> ``force``; ``--x-mm`` -> ``x_mm``; ``--wrench`` -> ``wrench_N_Nm``
    (the record's name carries the unit); ``--translation-sigma-um`` ->
    ``translation_sigma_m`` (the command line's unit, SI in the record).
    """
    base = option.lstrip("-").replace("-", "_")
    if base in names:
        return base
    for name in names:
        if name.startswith(base + "_"):
            return name
    for suffix in UNIT_SUFFIXES:
        if base.endswith(suffix):
            stem = base[: -len(suffix)]
            for name in names:
                if name.startswith(stem + "_"):
                    return name
    return None


def fields_of(options) -> list[str]:
    """The field names of an options record (a dataclass), or none."""
    if options is None or not dataclasses.is_dataclass(options):
        return []
    return [f.name for f in dataclasses.fields(options)]


def field_at_fault(where: str | None, options, names: list[str]) -> str | None:
    """The request field an error's ``where`` names: its first option, or the path field
    whose value the ``where`` starts with (a file:line of that file)."""
    if not where:
        return None
    for option in OPTION.findall(where):
        name = option_field(option, names)
        if name is not None:
            return name
    for name in names:
        value = getattr(options, name, None)
        if isinstance(value, (str, Path)) and str(value) and \
                str(where).startswith(str(value)):
            return name
    return None


def describe(err: BaseException, ws: Path | None, options=None) -> dict | None:
    """``{"status", "detail", "field", "options"}`` for a refusal; None for a bug.

    ``ws``: the workspace, whose absolute prefix is taken off the paths of the line;
    ``options``: the request's options record (for the field names).
    """
    names = fields_of(options)
    where = None
    if isinstance(err, InputError):
        status, text, where = 400, str(err), err.where
    elif isinstance(err, OSError):
        text = (f"{err.filename}: " if err.filename else "") + f"{err.strerror or err}"
        # a name the file system cannot take is bad input; a refused write is a conflict
        status = 400 if err.errno in (errno.ENAMETOOLONG, errno.EINVAL) else 409
    elif type(err).__name__ == "EquilibriumError":
        status, text = 400, (f"nonlinear equilibrium: {err}; reduce the wrench or check the "
                             "joint stiffness")
    else:
        return None
    if ws is not None:
        text = text.replace(f"{ws}/", "")
        where = None if where is None else where.replace(f"{ws}/", "")
    text = " ".join(text.split())  # one line
    named = {opt: name for opt in dict.fromkeys(OPTION.findall(text))
             if (name := option_field(opt, names)) is not None}
    if where is not None and options is not None:
        rel = options if ws is None else _relative_paths(options, ws)
        fault = field_at_fault(where, rel, names)
    else:
        fault = None
    record = {"status": status, "detail": text, "field": fault, "options": named}
    if isinstance(err, Refused):  # the reasons as the job gave them, one record each
        record["refused"] = [{"text": _relative(r.text, ws)} for r in err.reasons]
    problems = getattr(err, "problems", None)  # a form's refusal: each line with its field
    if isinstance(problems, list):
        record["problems"] = [{"field": p.get("field"), "detail": _relative(p["detail"], ws)}
                              for p in problems]
        # the form's key its first line names is the field at fault
        if problems and problems[0].get("field"):
            record["field"] = problems[0]["field"]
    return record


def _relative(text: str, ws: Path | None) -> str:
    """``text`` on one line, the workspace's absolute prefix taken off its paths."""
    return " ".join((text if ws is None else text.replace(f"{ws}/", "")).split())


def relative_to_workspace(ws: Path, doc: Any) -> Any:
    """``doc`` with the workspace's absolute paths written relative to it."""
    if isinstance(doc, dict):
        return {k: relative_to_workspace(ws, v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [relative_to_workspace(ws, v) for v in doc]
    if isinstance(doc, str):
        return doc.replace(f"{ws}/", "")
    return doc


def _relative_paths(options, ws: Path):
    """The options with workspace paths written relative to it (to match a ``where``)."""
    changes = {}
    for name in fields_of(options):
        value = getattr(options, name)
        if isinstance(value, (str, Path)) and str(value).startswith(f"{ws}/"):
            changes[name] = str(value)[len(str(ws)) + 1:]
    return dataclasses.replace(options, **changes) if changes else options
