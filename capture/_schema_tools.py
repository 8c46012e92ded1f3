"""Shared by the declared input schemas: one-line errors and generated docs."""

from __future__ import annotations

import typing

__all__ = ["describe_validation_error", "fields_markdown", "key_text", "short_repr", "MIN_TIME_STEP_S"]

# No motion-capture or control clock ticks faster than 100 kHz (a session's rate is at most that,
# ``_session_schema.MAX_RATE_HZ``): rows of a table closer than this in time were not sampled by one.
MIN_TIME_STEP_S = 1e-5


def key_text(key):
    """A document key as shown in a one-line message: as is when plain, quoted when it holds odd characters."""
    text = str(key)
    return text if text and text.isprintable() and text.strip() == text and '"' not in text else repr(text)


def short_repr(value, most=60):
    """repr(value), cut to ``most`` characters for a one-line message."""
    shown = repr(value)
    return shown if len(shown) <= most else shown[:most - 3] + "..."


def describe_validation_error(exc):
    """(where, value, expected) of a pydantic ValidationError's first error, for a one-line message."""
    err = exc.errors()[0]
    where = ".".join(map(key_text, err["loc"]))
    ctx = err.get("ctx") or {}
    kind = err["type"]
    bound = {"greater_than_equal": ">=", "less_than_equal": "<=", "greater_than": ">", "less_than": "<"}
    if kind in bound:
        expected = f"a value {bound[kind]} {next(iter(ctx.values()))}"
    elif kind == "missing":
        expected = "a value (the key is missing)"
    elif kind == "extra_forbidden":
        expected = "no such key (see docs/schemas.md)"
    elif kind == "literal_error":
        expected = f"one of {ctx.get('expected')}"
    elif kind == "string_too_short":
        expected = "a non-empty string"
    elif kind == "too_short":
        expected = f"at least {ctx.get('min_length')} items (it has {ctx.get('actual_length')})"
    elif kind == "too_long":
        expected = f"at most {ctx.get('max_length')} items (it has {ctx.get('actual_length')})"
    elif kind == "value_error":
        expected = err["msg"].removeprefix("Value error, ")
    else:
        expected = {"bool_type": "true or false", "int_type": "an integer", "float_type": "a number",
                    "string_type": "a string", "model_type": "an object", "dict_type": "an object",
                    "list_type": "a list", "finite_number": "a finite number"}.get(kind, err["msg"].lower())
    return where, err.get("input"), expected


def _type_name(annotation):
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Literal:
        return "string"
    if origin is typing.Union and type(None) in args:
        return _type_name(next(a for a in args if a is not type(None))) + " or null"
    if origin is list:
        return f"list of {_type_name(args[0])}" if args else "list"
    if origin is dict:
        return "object"
    if getattr(annotation, "__metadata__", None):  # Annotated
        return _type_name(args[0])
    return {bool: "boolean", int: "integer", float: "number", str: "string"}.get(annotation, "object")


def _number(x):
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e12 else f"{x:g}"


def _allowed(field):
    parts = []
    args = typing.get_args(field.annotation)
    if typing.get_origin(field.annotation) is typing.Literal:
        parts.append(", ".join(f'"{a}"' for a in args))
    lo = hi = None
    for m in field.metadata:
        for attr, sign in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            if getattr(m, attr, None) is not None:
                parts.append(f"{sign} {_number(getattr(m, attr))}")
        lo = getattr(m, "min_length", None) if getattr(m, "min_length", None) is not None else lo
        hi = getattr(m, "max_length", None) if getattr(m, "max_length", None) is not None else hi
    if _type_name(field.annotation).startswith("string"):
        if lo:
            parts.append("non-empty")
    elif lo is not None and lo == hi:
        parts.append(f"exactly {lo} items")
    elif lo is not None or hi is not None:
        parts.append(f"{lo or 0} to {hi} items" if hi is not None else f"at least {lo} items")
    return "; ".join(parts) or "-"


def _default(field):
    if field.is_required():
        return "required"
    value = field.get_default(call_default_factory=True)
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)


def fields_markdown(model, prefix=""):
    """Markdown rows (key, type, default, allowed, meaning) of a pydantic model, nested models flattened."""
    rows = []
    for name, field in model.model_fields.items():
        key = f"{prefix}{name}"
        sub = field.annotation
        if isinstance(sub, type) and hasattr(sub, "model_fields"):
            rows += fields_markdown(sub, f"{key}.")
            continue
        rows.append(f"| `{key}` | {_type_name(field.annotation)} | {_default(field)} | {_allowed(field)} | "
                    f"{field.description or ''} |")
    return rows
