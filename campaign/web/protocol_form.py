"""The Plan view's protocol form, generated from the protocol reader's own schema.

:func:`form_fields` walks :class:`campaign.protocol.Protocol` (the pydantic model
``load_protocol`` validates with), so a key added to the reader appears in the form
without a change here. A field is named by the key path the command line's messages
use (``campaign.tests``, ``load_cases[1].force_N``, ``instruments.pose.noise.translation_um``);
the rows of ``[[load_cases]]`` and ``[[zones]]`` and the ``[instruments.ROLE]`` tables
are collections the page adds rows to and removes them from.

Values travel as the text the user typed. :func:`build_document` turns them into a
TOML document by each field's kind (number, list of numbers, inline table, date,
true/false, text); text that does not read as its kind is written as typed, so that
the protocol reader refuses it with the command line's own message. An empty text
leaves the key out (the reader's default applies).
"""

from __future__ import annotations

import dataclasses
import datetime
import re
import tomllib
import types
import typing

from pydantic import BaseModel

#: collections of the protocol: key -> "rows" (an array of tables) or "roles" (named tables)
ROWS = ("load_cases", "zones")
ROLES = ("instruments",)
#: a key the reader reads inside ``options`` (Protocol.reflectors), given a field of its own
REFLECTORS = "options.reflectors_mm"
ROLE_NAME = re.compile(r"^[A-Za-z0-9_-]{1,40}$")
#: unit of a key from its name's suffix (the protocol's convention: units in key names)
UNITS = (("_deg_s2", "deg/s\u00b2"), ("_deg_s", "deg/s"), ("_deg", "deg"), ("_mm", "mm"),
         ("_um", "\u00b5m"), ("_urad", "\u00b5rad"), ("_N_m", "N m"), ("_N", "N"),
         ("_kg", "kg"), ("_pct", "%"), ("stiffness", "N m/rad"))


class FormError(ValueError):
    """A form value that cannot become TOML (``key`` names its field)."""

    def __init__(self, key: str, message: str) -> None:
        self.key = key
        super().__init__(f"{key}: {message}")


@dataclasses.dataclass(frozen=True)
class FormField:
    """One leaf key of the protocol.

    key: its path with ``*`` for a row index or role (``load_cases[*].name``,
    ``instruments.*.driver``); kind: text, choice, bool, int, float, vector, date or
    table; size: the length of a vector; unit: of the numbers, from the key's name;
    required: the reader refuses the protocol without it; default: the reader's
    default as text; help: the schema's docstring of the table.
    """

    key: str
    section: str
    kind: str
    size: int | None = None
    choices: tuple[str, ...] = ()
    unit: str = ""
    required: bool = False
    default: str = ""
    help: str = ""
    suggestions: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {"key": self.key, "section": self.section, "kind": self.kind,
                "size": self.size, "choices": list(self.choices), "unit": self.unit,
                "required": self.required, "default": self.default, "help": self.help,
                "suggestions": list(self.suggestions)}


def _unwrap(annotation):
    """(type without None and Annotated, optional?)."""
    optional = False
    while True:
        origin = typing.get_origin(annotation)
        if origin is typing.Annotated:
            annotation = typing.get_args(annotation)[0]
        elif origin in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            optional = optional or len(args) < len(typing.get_args(annotation))
            if len(args) != 1:
                return annotation, optional
            annotation = args[0]
        else:
            return annotation, optional


def _kind(annotation) -> tuple[str, int | None, tuple[str, ...]]:
    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        return "choice", None, tuple(str(a) for a in typing.get_args(annotation))
    if origin is tuple:
        return "vector", len(typing.get_args(annotation)), ()
    if origin is dict or annotation is dict:
        return "table", None, ()
    if origin is list and any(isinstance(a, type) and issubclass(a, BaseModel)
                              for a in typing.get_args(annotation)):
        # rows of tables inside a section (``[[fake_lab.links]]``): one field holding an
        # inline TOML array of tables, which the reader checks with its own messages
        return "table", None, ()
    if annotation is bool:
        return "bool", None, ("true", "false")
    if annotation is int:
        return "int", None, ()
    if annotation is float:
        return "float", None, ()
    if annotation is datetime.date:
        return "date", None, ()
    return "text", None, ()


def _unit(name: str) -> str:
    for suffix, unit in UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def _model_fields(model: type[BaseModel], prefix: str, section: str, optional_parent: bool):
    doc = " ".join((model.__doc__ or "").split())
    for name, info in model.model_fields.items():
        annotation, optional = _unwrap(info.annotation)
        key = f"{prefix}.{name}" if prefix else name
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            yield from _model_fields(annotation, key, section, optional_parent or optional)
            continue
        kind, size, choices = _kind(annotation)
        default = "" if info.is_required() else value_text(info.get_default(
            call_default_factory=True))
        yield FormField(key=key, section=section, kind=kind, size=size, choices=choices,
                        unit=_unit(name), required=info.is_required() and not optional_parent,
                        default=default, help=doc)
        if name == "options" and prefix.endswith(".*"):
            yield FormField(key=f"{prefix}.{REFLECTORS}", section=section, kind="table",
                            unit="mm", help="reflectors_mm = { NAME = [x, y, z], ... } (mm, "
                            "tool frame): three or more reflectors of the pose instrument")


def form_fields(suggest: bool = True) -> list[FormField]:
    """Every leaf key of the protocol schema, in the schema's order (``suggest``: with the
    driver registry's names as the driver field's suggestions)."""
    from campaign.protocol import Protocol

    out: list[FormField] = []
    for name, info in Protocol.model_fields.items():
        annotation, optional = _unwrap(info.annotation)
        origin = typing.get_origin(annotation)
        if name in ROWS and origin is list:
            inner = typing.get_args(annotation)[0]
            out += _model_fields(inner, f"{name}[*]", name, False)
        elif name in ROLES and origin is dict:
            inner = typing.get_args(annotation)[1]
            out += _model_fields(inner, f"{name}.*", name, False)
        elif isinstance(annotation, type) and issubclass(annotation, BaseModel):
            out += _model_fields(annotation, name, name, optional)
        else:  # a top-level scalar key (none today): a field of its own section
            kind, size, choices = _kind(annotation)
            out.append(FormField(key=name, section=name, kind=kind, size=size, choices=choices))
    return _suggest(out) if suggest else out


def _suggest(fields: list[FormField]) -> list[FormField]:
    """Drivers: the registry's names; addresses: those of the shipped protocols."""
    try:
        from drivers.registry import available_drivers

        drivers = tuple(sorted(available_drivers()))
    except ImportError:
        drivers = ()
    out = []
    for f in fields:
        if f.key == "instruments.*.driver":
            f = dataclasses.replace(f, suggestions=drivers)
        out.append(f)
    return out


# ---- values <-> text ----------------------------------------------------------------

def _num(v) -> str:
    return "true" if v is True else "false" if v is False else (
        str(v) if isinstance(v, int) else repr(float(v)))


def _inline(v) -> str:
    """A TOML inline value (tables as ``{ a = 1, b = [2, 3] }``)."""
    if isinstance(v, dict):
        if not v:
            return "{}"
        parts = []
        for k, x in v.items():
            name = k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else '"' + k.replace(
                "\\", "\\\\").replace('"', '\\"') + '"'
            parts.append(f"{name} = {_inline(x)}")
        return "{ " + ", ".join(parts) + " }"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_inline(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, datetime.date):
        return v.isoformat()
    return _num(v)


def value_text(v) -> str:
    """The text a field shows for the value ``v`` of a TOML document."""
    if v is None:
        return ""
    if isinstance(v, bool | int | float):
        return _num(v)
    if isinstance(v, list | tuple):
        if all(isinstance(x, int | float) and not isinstance(x, bool) for x in v):
            return ", ".join(_num(x) for x in v)
        return _inline(list(v))
    if isinstance(v, dict):
        return _inline(v)
    if isinstance(v, datetime.date):
        return v.isoformat()
    return str(v)


def _number(t: str):
    if re.fullmatch(r"[+-]?\d+", t):
        return int(t)
    return float(t)


def parse_value(key: str, kind: str, text: str):
    """The TOML value of ``text`` for a field of ``kind``; the text itself where it does
    not read so (the reader refuses it then, with the command line's message)."""
    t = text.strip()
    try:
        if kind == "bool":
            return {"true": True, "false": False}.get(t.lower(), t)
        if kind in ("int", "float"):
            return _number(t)
        if kind == "vector":
            inner = t[1:-1] if t.startswith("[") and t.endswith("]") else t
            return [_number(x.strip()) for x in inner.split(",")]
        if kind == "date":
            return datetime.date.fromisoformat(t)
    except ValueError:
        return t
    if kind == "table":
        try:
            return tomllib.loads(f"v = {t}")["v"]
        except (tomllib.TOMLDecodeError, ValueError) as err:  # ValueError: a 4300-digit int
            raise FormError(key, f"expected an inline table such as {{ q1 = 0, q4 = 45 }} "
                                 f"(or an array of them): {err}") from None
    return t


# ---- documents <-> form values ------------------------------------------------------

def _template(key: str) -> str:
    """``load_cases[2].name`` -> ``load_cases[*].name``; ``instruments.pose.driver`` ->
    ``instruments.*.driver``."""
    key = re.sub(r"\[\d+\]", "[*]", key)
    for name in ROLES:
        if key.startswith(name + "."):
            rest = key[len(name) + 1:].split(".", 1)
            key = f"{name}.*." + (rest[1] if len(rest) > 1 else "")
    return key


def _path(key: str) -> list[str | int]:
    out: list[str | int] = []
    for part in key.split("."):
        m = re.fullmatch(r"([^\[\]]+)((?:\[\d+\])*)", part)
        if not m:
            raise FormError(key, "not a key of the protocol form")
        out.append(m.group(1))
        out += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return out


def _get(doc, path):
    for part in path:
        if isinstance(part, int):
            doc = doc[part] if isinstance(doc, list) and part < len(doc) else None
        else:
            doc = doc.get(part) if isinstance(doc, dict) else None
        if doc is None:
            return None
    return doc


def form_values(doc: dict) -> dict[str, str]:
    """Every field's text for the TOML document ``doc`` (keys without a value left out).

    Raises FormError for a key of ``doc`` that no field holds (an unknown key: the
    reader would refuse it too, naming it).
    """
    fields = {f.key: f for f in form_fields(suggest=False)}
    out: dict[str, str] = {}
    entries = [("", doc)]
    for name in ROWS:
        rows = doc.get(name)
        if isinstance(rows, list):
            entries += [(f"{name}[{i}]", row) for i, row in enumerate(rows)]
    for name in ROLES:
        roles = doc.get(name)
        if isinstance(roles, dict):
            entries += [(f"{name}.{role}", spec) for role, spec in roles.items()]
    collections = set(ROWS) | set(ROLES)
    for prefix, table in entries:
        if not isinstance(table, dict):
            raise FormError(prefix or "(top level)", "expected a table")
        _flatten(table, prefix, fields, out, skip=collections if not prefix else set())
    return out


def _flatten(table: dict, prefix: str, fields: dict, out: dict, skip: set) -> None:
    for name, value in table.items():
        if name in skip:
            continue
        key = f"{prefix}.{name}" if prefix else name
        tpl = _template(key)
        if tpl in fields:
            if tpl.endswith(".options") and isinstance(value, dict) and \
                    "reflectors_mm" in value:
                value = {k: v for k, v in value.items() if k != "reflectors_mm"}
                out[f"{key}.reflectors_mm"] = value_text(table[name]["reflectors_mm"])
                if not value:
                    continue
            out[key] = value_text(value)
        elif isinstance(value, dict) and any(f.startswith(tpl + ".") for f in fields):
            _flatten(value, key, fields, out, set())
        else:
            raise FormError(key, "unknown key (the protocol reader does not read it)")


def build_document(values: dict[str, str]) -> dict:
    """A TOML document from form values (key -> text); empty texts are left out.

    Rows are kept in their index order and renumbered (a removed row leaves no gap).

    Raises FormError naming a key that is no field of the form, or a table value that
    is not TOML.
    """
    fields = {f.key: f for f in form_fields(suggest=False)}
    doc: dict = {}
    rows: dict[str, dict[int, dict]] = {name: {} for name in ROWS}
    # shorter keys first: ``options`` before ``options.reflectors_mm``
    for key in sorted(values, key=lambda k: (k.count("."), k)):
        text = values[key]
        spec = fields.get(_template(key))
        if spec is None:
            raise FormError(key, "not a key of the protocol form")
        if not text.strip():
            continue
        path = _path(key)
        if path[0] in ROLES and not ROLE_NAME.match(str(path[1])):
            raise FormError(key, "instrument role: letters, digits, '_' and '-' only")
        value = parse_value(key, spec.kind, text)
        if path[0] in ROWS:
            target = rows[path[0]].setdefault(int(path[1]), {})
            path = path[2:]
        else:
            target = doc
        for part in path[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise FormError(key, "its table is given as a value")
        if isinstance(target.get(path[-1]), dict) and isinstance(value, dict):
            target[path[-1]] = {**value, **target[path[-1]]}
        else:
            target[path[-1]] = value
    for name in ROWS:
        if rows[name]:
            doc[name] = [rows[name][i] for i in sorted(rows[name])]
    return doc


def field_keys(values: dict[str, str]) -> list[str]:
    """The expanded keys of the form holding ``values``: every field of every row, and
    each row and role itself (``load_cases[2]``: what a check of the whole row names)."""
    fields = form_fields(suggest=False)
    rows = {name: sorted({int(m.group(1)) for k in values
                          for m in [re.match(rf"{name}\[(\d+)\]", k)] if m}) for name in ROWS}
    roles = {name: sorted({k.split(".")[1] for k in values if k.startswith(name + ".")})
             for name in ROLES}
    out = [f"{name}[{i}]" for name in ROWS for i in rows[name]]  # a row's own checks
    out += [f"{name}.{r}" for name in ROLES for r in roles[name]]
    for f in fields:
        if "[*]" in f.key:
            name = f.key.split("[", 1)[0]
            out += [f.key.replace("[*]", f"[{i}]") for i in rows[name]]
        elif f.key.startswith(tuple(n + ".*." for n in ROLES)):
            name = f.key.split(".", 1)[0]
            out += [f.key.replace(".*.", f".{r}.", 1) for r in roles[name]]
        else:
            out.append(f.key)
    return out


def field_of(line: str, keys: list[str]) -> str | None:
    """The form key a message line names (``FILE:LINE: KEY: why``; KEY may go deeper than
    the field, e.g. ``tool.xyz_mm[1]`` or ``sampling.fixed_deg.q1``)."""
    hits = [k for k in keys
            if re.search(rf"(^|[\s:]){re.escape(k)}(?=[:.\[\s]|$)", line)]
    return max(hits, key=len) if hits else None
