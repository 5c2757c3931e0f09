"""Rejection reasons of received payloads: a fixed, bounded vocabulary.

A service counts every payload it cannot decode or validate under a *reason* (a Status
``rejected`` key). Reasons must form a small set whatever a hostile peer sends, so a
reason never contains text from the payload:

* ``invalid {Model}: not JSON`` — the bytes are not (UTF-8) JSON, or nest too deep;
* ``invalid {Model}: {field}`` — ``field`` is a field *of the schema* whose value failed
  (type, range, a column check naming it);
* ``invalid {Model}: unknown field`` — a key the schema does not have;
* ``invalid {Model}: value`` — a whole-message check that names no field;
* ``invalid {Model}: undecodable`` — any other exception raised while decoding (e.g. an
  ``OverflowError`` or ``RecursionError``), so no input can escape as a crash.

So a model with *F* fields has at most *F* + 4 reasons. The offending value and location,
as sent, go only to the (rate-limited) log line: :func:`rejection_detail`, truncated.
"""

from __future__ import annotations

import re

from pydantic import BaseModel, ValidationError

DETAIL_CHARS = 200
"""Longest detail string logged for one rejection (the payload may be megabytes)."""

_LEADING_NAME = re.compile(r"(?:Value error, )?(?:column )?'?([A-Za-z_][A-Za-z0-9_]*)")


def rejection_reason(model: type[BaseModel], exc: BaseException) -> str:
    """The bounded reason for ``exc``, raised while decoding a ``model`` payload."""
    name = model.__name__
    if not isinstance(exc, ValidationError):
        return f"invalid {name}: undecodable"
    errors = exc.errors(include_url=False, include_input=False)
    if not errors:
        return f"invalid {name}: value"
    err = errors[0]
    if err["type"] == "json_invalid":
        return f"invalid {name}: not JSON"
    if err["type"] in ("model_type", "model_attributes_type", "dict_type") and not err["loc"]:
        return f"invalid {name}: not JSON"  # valid JSON, but not an object
    loc = [p for p in err["loc"] if isinstance(p, str)]
    if loc:
        field = loc[0]
    else:  # a model-level check: its message starts with the column name
        m = _LEADING_NAME.match(err["msg"])
        field = m.group(1) if m else ""
        if field not in model.model_fields:
            return f"invalid {name}: value"
    if field not in model.model_fields:
        return f"invalid {name}: unknown field"
    return f"invalid {name}: {field}"


def rejection_detail(exc: BaseException) -> str:
    """Where and why, for the log only: ``loc: message``, at most :data:`DETAIL_CHARS`."""
    if isinstance(exc, ValidationError):
        errors = exc.errors(include_url=False, include_input=False)
        if errors:
            err = errors[0]
            loc = ".".join(str(p) for p in err["loc"]) or "(payload)"
            text = f"{loc}: {err['msg']}"
        else:
            text = str(exc)
    else:
        text = f"{type(exc).__name__}: {exc}"
    return text if len(text) <= DETAIL_CHARS else text[: DETAIL_CHARS - 3] + "..."


def decode(model: type[BaseModel], payload: bytes | bytearray | memoryview | str):
    """``(message, None)`` or ``(None, exc)``: never raises for any payload."""
    try:
        if isinstance(payload, memoryview):
            payload = bytes(payload)
        return model.model_validate_json(payload), None
    except Exception as e:  # every decoding failure is a rejection, never a crash
        return None, e
