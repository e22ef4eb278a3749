"""Request bodies are checked before any handler sees them: size (413), then for JSON: UTF-8, syntax, nesting depth,
finite numbers and integers Python can hold (422), each error naming the field and the rule.

One ASGI middleware for every route, so no handler can forget a check and no recursive code ever walks an unchecked
body: the depth and number checks below are iterative, and the one recursive step (the stdlib parser) turns too-deep
input into a RecursionError that is caught here.
"""

from __future__ import annotations

import json
import math
from typing import Any

from starlette.datastructures import Headers

from rubric import sheet_files

MAX_ERRORS = 20


def is_json(content_type: str | None) -> bool:
    media = (content_type or "").split(";")[0].strip().lower()
    return media == "application/json" or (media.startswith("application/") and media.endswith("+json"))


def json_problems(body: bytes, *, max_depth: int) -> list[dict[str, str]]:
    """Why `body` is not acceptable JSON, as [{field, rule}]; [] when it is (an empty body is the handler's to refuse)."""
    if not body:
        return []
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        return [{"field": "body", "rule": f"must be UTF-8 encoded JSON; byte {exc.start} is not valid UTF-8"}]
    try:  # an integer longer than Python's digit limit becomes a marker that value_problems names by its field
        value = json.loads(text, parse_int=sheet_files.whole_number)
    except RecursionError:
        return [{"field": "body", "rule": f"must be nested at most {max_depth} levels deep"}]
    except ValueError as exc:  # JSONDecodeError
        return [{"field": "body", "rule": f"must be valid JSON: {exc}"}]
    return value_problems(value, max_depth=max_depth)


def value_problems(value: Any, *, max_depth: int) -> list[dict[str, str]]:
    """Containers nested deeper than max_depth, NaN/Infinity (which Python's parser accepts) and integers past
    rubric.sheet_files.MAX_INTEGER_DIGITS digits (which it cannot hold), by path; iterative.

    Paths are dotted from the body's top level (`sheet.answers.C5.pair_friction`), as in every other error."""
    problems: list[dict[str, str]] = []
    stack: list[tuple[Any, tuple[str, ...]]] = [(value, ())]
    while stack and len(problems) < MAX_ERRORS:
        item, path = stack.pop()
        field = ".".join(path) or "body"
        if isinstance(item, float) and not math.isfinite(item):
            problems.append({"field": field, "rule": f"must be a finite number, got {item}"})
        elif isinstance(item, sheet_files.TooLongInteger):
            problems.append({"field": field, "rule": item.rule})
        elif isinstance(item, (dict, list)):
            if len(path) >= max_depth:
                problems.append({"field": field, "rule": f"must be nested at most {max_depth} levels deep"})
                continue
            children = item.items() if isinstance(item, dict) else enumerate(item)
            stack.extend((child, (*path, str(key))) for key, child in reversed(list(children)))
    return problems



def replaying(body: bytes, receive):
    """An ASGI receive that hands the app the body already read, whole, then defers to the real one (disconnects)."""
    replayed = False

    async def replay():
        nonlocal replayed
        if replayed:
            return await receive()
        replayed = True
        return {"type": "http.request", "body": body, "more_body": False}

    return replay

class BodyGuard:
    """ASGI middleware: 413 for a declared or streamed body over max_bytes (any content type), 422 for a JSON body
    that is not UTF-8, not JSON, too deep or holds NaN/Infinity; the body is read once, whole, and replayed."""

    def __init__(self, app, *, max_bytes: int, max_depth: int):
        self.app, self.max_bytes, self.max_depth = app, max_bytes, max_depth

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = Headers(scope=scope)
        declared = headers.get("content-length", "")
        if declared.isdigit() and int(declared) > self.max_bytes:
            return await _send_error(send, 413, "request body too large", [self._size_rule()])
        buffer, more = bytearray(), True  # bytearray: many tiny chunks must not cost quadratic copying
        while more:  # read whole, bounded: a limit raised inside the app's own read would become FastAPI's 400
            message = await receive()
            if message["type"] != "http.request":
                return  # the client went away before sending its body: nobody to answer
            buffer += message.get("body", b"")
            more = message.get("more_body", False)
            if len(buffer) > self.max_bytes:
                return await _send_error(send, 413, "request body too large", [self._size_rule()])
        body = bytes(buffer)
        if is_json(headers.get("content-type")) and (problems := json_problems(body, max_depth=self.max_depth)):
            return await _send_error(send, 422, "invalid JSON body", problems)
        await self.app(scope, replaying(body, receive), send)

    def _size_rule(self) -> dict[str, str]:
        return {"field": "body", "rule": f"at most {self.max_bytes} bytes"}


async def _send_error(send, status: int, detail: str, errors: list[dict[str, str]]) -> None:
    body = json.dumps({"detail": detail, "errors": errors}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})
