"""Every error is JSON {detail, errors: [{field, rule}]}; bodies over the size limit are refused before parsing."""

from __future__ import annotations

import json

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException


def field_errors(lines: list[str], prefix: str = "") -> list[dict[str, str]]:
    """'field.path: rule' lines (rubric.describe_errors) as [{field, rule}]."""
    out = []
    for line in lines:
        field, sep, rule = line.partition(": ")
        field, rule = (field, rule) if sep else ("", line)
        out.append({"field": ".".join(p for p in (prefix, field) if p), "rule": rule})
    return out


def error(status: int, detail: str, errors: list[dict[str, str]] | None = None, headers=None) -> JSONResponse:
    return JSONResponse({"detail": detail, "errors": errors or []}, status_code=status, headers=headers)


async def _validation(_: Request, exc: RequestValidationError) -> JSONResponse:
    errors = [{"field": ".".join(str(p) for p in e["loc"]), "rule": e["msg"]} for e in exc.errors()]
    return error(422, "invalid request", errors)


async def _http(_: Request, exc: StarletteHTTPException) -> JSONResponse:
    return error(exc.status_code, str(exc.detail), headers=getattr(exc, "headers", None))


class BodyLimit:
    """ASGI middleware: 413 for a declared or streamed body over max_bytes, before any handler reads it."""

    def __init__(self, app, max_bytes: int):
        self.app, self.max_bytes = app, max_bytes

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        declared = dict(scope["headers"]).get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            return await self._refuse(send)
        seen = 0

        async def limited():
            nonlocal seen
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.max_bytes:
                raise _TooLarge
            return message

        try:
            await self.app(scope, limited, send)
        except _TooLarge:
            await self._refuse(send)

    async def _refuse(self, send):
        body = json.dumps({"detail": "request body too large",
                           "errors": [{"field": "body", "rule": f"at most {self.max_bytes} bytes"}]}).encode()
        await send({"type": "http.response.start", "status": 413,
                    "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})


class _TooLarge(Exception):
    pass


def install(app: FastAPI, *, max_bytes: int) -> None:
    app.add_exception_handler(RequestValidationError, _validation)
    app.add_exception_handler(StarletteHTTPException, _http)
    app.add_middleware(BodyLimit, max_bytes=max_bytes)
