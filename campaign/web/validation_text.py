"""A request the API's models refuse, as sentences a person reads: each names the field
and what it accepts (``trials: at most 5000 (got 9000)``), not pydantic's wording
(``body.trials: Input should be less than or equal to 5000``)."""

from __future__ import annotations

#: pydantic error type -> the sentence, from the error's ``ctx`` (its bound or choices)
_BOUNDS = {
    "less_than_equal": "at most {le}",
    "less_than": "less than {lt}",
    "greater_than_equal": "at least {ge}",
    "greater_than": "more than {gt}",
    "string_too_long": "at most {max_length} characters",
    "string_too_short": "at least {min_length} characters",
    "too_long": "at most {max_length} items",
    "too_short": "at least {min_length} items",
    "literal_error": "one of {expected}",
    "enum": "one of {expected}",
    "string_pattern_mismatch": "text of the form {pattern}",
}
#: pydantic error type -> the sentence, without context
_KINDS = {
    "missing": "required",
    "extra_forbidden": "not a field of this request",
    "int_parsing": "a whole number", "int_type": "a whole number",
    "int_from_float": "a whole number",
    "float_parsing": "a number", "float_type": "a number",
    "finite_number": "a finite number",
    "bool_parsing": "true or false", "bool_type": "true or false",
    "string_type": "text", "list_type": "a list", "dict_type": "an object",
    "json_invalid": "a valid JSON document",
}
#: where an error's location starts (the part of the request, not a field)
_PARTS = ("body", "query", "path", "header", "cookie")


def field_name(loc: tuple) -> str:
    """The request field of an error's location (``("body", "q_deg", 1)`` -> ``q_deg[1]``);
    ``request`` for the request as a whole."""
    parts = list(loc[1:] if loc and loc[0] in _PARTS else loc)
    text = ""
    for p in parts:
        text += f"[{p}]" if isinstance(p, int) else (f".{p}" if text else str(p))
    return text or "request"


def sentence(error: dict) -> str:
    """One refused field as ``FIELD: expected (got VALUE)``."""
    kind, ctx = error.get("type", ""), error.get("ctx") or {}
    if kind in _BOUNDS:
        try:
            wanted = _BOUNDS[kind].format(**ctx)
        except (KeyError, IndexError):
            wanted = str(error.get("msg", ""))
    else:
        wanted = _KINDS.get(kind) or str(error.get("msg", "")).removeprefix("Value error, ")
    text = f"{field_name(tuple(error.get('loc', ())))}: {wanted}"
    if kind in _BOUNDS or kind in _KINDS and kind not in ("missing", "json_invalid"):
        got = error.get("input")
        if isinstance(got, int | float | str | bool) and len(repr(got)) <= 40:
            text += f" (got {got!r})" if isinstance(got, str) else f" (got {got})"
    return text


def refusal(errors: list[dict]) -> dict:
    """``{"detail": the sentences joined by '; ', "field": the first field at fault}``."""
    return {"detail": "; ".join(sentence(e) for e in errors),
            "field": field_name(tuple(errors[0].get("loc", ()))) if errors else None}
