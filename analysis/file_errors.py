"""Turn pydantic validation errors into messages that name the file, key and line.

TOML parsers do not keep positions, so the line of a key is found by scanning
the text (array-of-tables headers are counted to reach the right element).
YAML nodes carry their own marks.
"""

from __future__ import annotations

import re
import sys
import tomllib
from collections.abc import Sequence
from pathlib import Path

from pydantic import ValidationError

from analysis.errors import InputError


def _dotted(loc: Sequence) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def toml_line(text: str, loc: Sequence) -> int | None:
    """1-based line of the key ``loc`` (e.g. ``("joints", 2, "alpha")``) in TOML text."""
    lines = text.splitlines()
    start = 0
    end = len(lines)
    prefix: list[str] = []
    i = 0
    found: int | None = None
    while i < len(loc):
        part = loc[i]
        if isinstance(part, int):
            i += 1
            continue
        name = str(part)
        index = loc[i + 1] if i + 1 < len(loc) and isinstance(loc[i + 1], int) else None
        table = ".".join([*prefix, name])
        header = re.compile(r"^\s*\[\[?\s*" + re.escape(table) + r"\s*\]\]?\s*(#.*)?$")
        # sub-table headers ([a.b]) lie after the parent's body: search to the end
        headers = [k for k in range(start, len(lines)) if header.match(lines[k])]
        if headers:
            k = headers[index] if index is not None and index < len(headers) else headers[0]
            found = k + 1
            start = k + 1
            nxt = [m for m in range(start, len(lines)) if re.match(r"^\s*\[", lines[m])]
            end = nxt[0] if nxt else len(lines)
            prefix.append(name)
            i += 2 if index is not None else 1
            continue
        key = re.compile(r"^\s*" + re.escape(name) + r"\s*=")
        for k in range(start, end):
            if key.match(lines[k]):
                return k + 1
        dotted = re.compile(r"^\s*\[\[?\s*" + re.escape(table) + r"\.")
        if i + 1 < len(loc) and isinstance(loc[i + 1], str) and any(
            dotted.match(line) for line in lines[start:]
        ):
            # only dotted headers such as [instruments.pose]: merge with the next part
            prefix.append(name)
            i += 1
            continue
        return found
    return found


def yaml_line(text: str, loc: Sequence) -> int | None:
    """1-based line of the key ``loc`` in YAML text (from the composed node marks)."""
    import yaml

    try:
        node = yaml.compose(text)
    except yaml.YAMLError:
        return None
    line = None
    for part in loc:
        if node is None:
            break
        if isinstance(node, yaml.MappingNode):
            match = [(k, v) for k, v in node.value if k.value == part]
            if not match:
                break
            line = match[0][0].start_mark.line + 1
            node = match[0][1]
        elif isinstance(node, yaml.SequenceNode) and isinstance(part, int):
            if part >= len(node.value):
                break
            node = node.value[part]
            line = node.start_mark.line + 1
        else:
            break
    return line


def input_error_from_validation(err: ValidationError, path: str, text: str) -> InputError:
    """One :class:`InputError` listing every problem as ``file:line: key: message``."""
    finder = yaml_line if path.endswith((".yaml", ".yml")) else toml_line
    problems = []
    for item in err.errors():
        loc = tuple(p for p in item["loc"] if p not in ("function-after",))
        line = finder(text, loc) if loc else None
        key = _dotted(loc) or "(top level)"
        msg = item["msg"]
        if item["type"] == "extra_forbidden":
            msg = "unknown key"
        if item["type"] == "missing":
            msg = "required key is missing"
        got = item.get("input")
        detail = f" (got {got!r})" if item["type"] not in ("missing", "extra_forbidden") and (
            isinstance(got, str | int | float | bool)
        ) else ""
        where = f"{path}:{line}" if line else path
        problems.append(f"{where}: {key}: {msg}{detail}")
    return InputError("\n".join(problems))


def read_utf8(path: Path, what: str) -> str:
    """The text of ``path``, which must be UTF-8 (a BOM is accepted and dropped).

    Raises
    ------
    InputError
        Unreadable, or not UTF-8 text: binary, UTF-16 or another encoding (the
        message names the byte offset and the likely cause).
    """
    try:
        data = Path(path).read_bytes()
    except OSError as err:
        raise InputError(f"cannot read {what}: {err.strerror}", where=str(path)) from err
    return decode_utf8(data, str(path), what)


def decode_utf8(data: bytes, where: str, what: str) -> str:
    """``data`` decoded as UTF-8 (BOM dropped), else an :class:`InputError` naming ``where``."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"{what} is UTF-16 text; save it as UTF-8", where=where)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise InputError(f"{what} is not UTF-8 text (binary, or another encoding): byte "
                         f"{err.start} on line {line}", where=where) from None
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise InputError(f"{what} is not text (NUL byte on line {line}; UTF-16 without a "
                         "byte-order mark, or a binary file)", where=where)
    # the same newline translation as text-mode reading
    return text.replace("\r\n", "\n").replace("\r", "\n")


#: a run of digits (TOML allows ``_`` between them) too long for Python's int(): over its
#: int-string limit (sys.get_int_max_str_digits, 4300 by default) the parsers raise a bare
#: ValueError with no position
_DIGITS = re.compile(r"[0-9](?:_?[0-9])*")


def huge_integer(path: Path, text: str) -> InputError | None:
    """The refusal of the first integer in ``text`` with more digits than Python reads
    (``file:line: key: ...``), or None if there is none."""
    limit = sys.get_int_max_str_digits()
    if not limit:
        return None
    for number, line in enumerate(text.splitlines(), 1):
        for m in _DIGITS.finditer(line):
            digits = m.group().replace("_", "")
            if len(digits) > limit:
                # the key the number is the value of (or an item of): the last
                # ``key =`` / ``key:`` before it
                key = re.search(r"([A-Za-z_][A-Za-z0-9_.-]*)[\"']?\s*[=:][^=:]*$",
                                line[:m.start()])
                name = f"{key.group(1)}: " if key else ""
                return InputError(f"{name}a number of {len(digits)} digits: more than "
                                  f"the {limit} a number may have; write a number of "
                                  "plausible size (with an exponent, e.g. 1e6)",
                                  where=f"{path}:{number}")
    return None


def read_mapping_file(path: Path, what: str) -> tuple[dict, str]:
    """Parse a TOML or YAML file whose top level is a table; returns (data, text).

    ``what`` names the kind of file in messages ("robot file", "protocol file").
    Errors name the file and, where the parser gives it, the line.
    """
    text = read_utf8(path, what)
    suffix = path.suffix.lower()
    if suffix in (".yaml", ".yml"):
        import yaml  # only YAML files pay for its import (command start-up time)

        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise InputError(f"not valid YAML: {err}", where=str(path)) from err
        except ValueError:  # an integer over Python's int-string limit
            raise huge_integer(path, text) or InputError(
                "not valid YAML: a value cannot be read", where=str(path)) from None
    elif suffix == ".toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise InputError(f"not valid TOML: {err}", where=str(path)) from err
        except ValueError:  # an integer over Python's int-string limit
            raise huge_integer(path, text) or InputError(
                "not valid TOML: a value cannot be read", where=str(path)) from None
    else:
        raise InputError(f"expected a .toml, .yaml or .yml {what}", where=str(path))
    if not isinstance(data, dict):
        raise InputError("expected a table of keys at the top level", where=str(path))
    return data, text


def read_json_object(path: Path, what: str) -> dict:
    """A JSON file whose top level is an object (UTF-8); errors name the file and line.

    Used for the records of a run (``metadata.json``): a damaged one is refused with
    a one-line message, never a traceback.
    """
    import json

    text = read_utf8(path, what)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise InputError(f"not valid JSON (line {err.lineno}, column {err.colno}): {err.msg}; "
                         "the run record is damaged", where=str(path)) from None
    except ValueError:  # an integer over Python's int-string limit
        raise huge_integer(path, text) or InputError(
            "not valid JSON: a value cannot be read; the run record is damaged",
            where=str(path)) from None
    if not isinstance(data, dict):
        raise InputError(f"expected a JSON object, found a {type(data).__name__}; the run "
                         "record is damaged", where=str(path))
    return data
