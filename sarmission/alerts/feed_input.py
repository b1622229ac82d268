"""What the operator feed accepts: every query parameter, header and body field, checked.

Anything else is a :class:`BadRequest` whose message becomes a one-line JSON 400 (or the status
it names): a client never sees a traceback, and a typo (``?folow=1``) is reported, not ignored.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Collection
from email.message import Message
from urllib.parse import parse_qsl

#: Longest request target accepted (the page and API use short ones).
MAX_TARGET = 2048
#: Largest request body (an acknowledgement is a few dozen bytes).
MAX_BODY = 4096
#: Longest operator name recorded with an acknowledgement or a decision.
MAX_BY = 64
#: Longest mission id accepted in a query.
MAX_MISSION = 128
_EVENT_ID = re.compile(r"[0-9]{1,18}")
_LENGTH = re.compile(r"[0-9]{1,9}")
_MAX_PARAMS = 8


class BadRequest(Exception):
    """Malformed input; answered with ``status`` (400 unless said) and the message."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


def parse_query(query: str, allowed: Collection[str]) -> dict[str, str]:
    """The query string as ``name -> value``; unknown names, repeats and excess are refused."""
    if not query:
        return {}
    try:
        pairs = parse_qsl(
            query, keep_blank_values=True, max_num_fields=_MAX_PARAMS, errors="strict"
        )
    except (ValueError, UnicodeDecodeError):
        raise BadRequest("malformed query string") from None
    params: dict[str, str] = {}
    for name, value in pairs:
        if name not in allowed:
            takes = ", ".join(sorted(allowed)) or "no parameters"
            raise BadRequest(f"unknown query parameter {name[:40]!r} (this path takes: {takes})")
        if name in params:
            raise BadRequest(f"query parameter {name!r} given twice")
        params[name] = value
    return params


def since(params: dict[str, str]) -> float | None:
    """``since``: a lock time in POSIX seconds (finite), None when absent."""
    text = params.get("since")
    if text is None:
        return None
    try:
        value = float(text) if len(text) <= 32 else math.nan
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise BadRequest("since must be POSIX seconds, e.g. since=1700000000.5")
    return value


def follow(params: dict[str, str]) -> bool:
    """``follow``: ``1``/``true``/``yes`` or ``0``/``false``/``no`` (default no)."""
    text = params.get("follow", "0").lower()
    if text in ("1", "true", "yes"):
        return True
    if text in ("0", "false", "no"):
        return False
    raise BadRequest("follow must be 1 or 0")


def last_event_id(headers: Message) -> int | None:
    """``Last-Event-ID`` sent by a reconnecting EventSource: an event number, None when absent."""
    values = headers.get_all("Last-Event-ID") or []
    if len(values) > 1:
        raise BadRequest("Last-Event-ID given twice")
    text = values[0].strip() if values else ""
    if not text:
        return None
    if not _EVENT_ID.fullmatch(text):
        raise BadRequest("Last-Event-ID must be an event number (up to 18 digits)")
    return int(text)


def content_length(headers: Message) -> int:
    """The body length of a request: ``Content-Length`` (0 when absent), at most MAX_BODY."""
    if headers.get("Transfer-Encoding") is not None:
        raise BadRequest("chunked bodies are not accepted: send Content-Length", 411)
    values = headers.get_all("Content-Length") or []
    if len(values) > 1:
        raise BadRequest("Content-Length given twice")
    text = values[0].strip() if values else "0"
    if not _LENGTH.fullmatch(text):
        raise BadRequest("Content-Length must be a number of bytes")
    length = int(text)
    if length > MAX_BODY:
        raise BadRequest(f"body larger than {MAX_BODY} bytes", 413)
    return length


def ack_by(body: bytes) -> str:
    """Who acknowledges, from an acknowledgement body: ``{}`` or ``{"by": "name"}`` with a name
    of 1-64 printable characters (default ``operator``)."""
    return _operator(body, "operator")


def decided_by(body: bytes) -> str:
    """Who confirms or dismisses, from the body ``{"by": "name"}`` (1-64 printable characters).
    Unlike an acknowledgement the name is required: a dismissal silences a place for the rest of
    the mission, so who made it must be on record."""
    return _operator(body, None)


def _operator(body: bytes, default: str | None) -> str:
    try:
        doc = json.loads(body) if body.strip() else {}
    except (ValueError, RecursionError):
        raise BadRequest('body must be a JSON object like {"by": "name"}') from None
    if not isinstance(doc, dict):
        raise BadRequest('body must be a JSON object like {"by": "name"}')
    unknown = set(doc) - {"by"}
    if unknown:
        raise BadRequest(f"unknown field {sorted(unknown)[0][:40]!r} (the body takes: by)")
    by = doc.get("by", default)
    if by is None:
        raise BadRequest('say who decides: send {"by": "name"}')
    if not isinstance(by, str) or not 1 <= len(by.strip()) <= MAX_BY or not by.isprintable():
        raise BadRequest(f"by must be a name of 1 to {MAX_BY} printable characters")
    return by.strip()


def mission(params: dict[str, str]) -> str | None:
    """``mission``: a mission id of 1-128 printable characters, None when absent."""
    text = params.get("mission")
    if text is None:
        return None
    if not 1 <= len(text) <= MAX_MISSION or not text.isprintable():
        raise BadRequest(f"mission must be a mission id of 1 to {MAX_MISSION} printable characters")
    return text
