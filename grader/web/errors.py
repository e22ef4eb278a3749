"""The one place errors become answers. Under /v1 every error is JSON {detail, errors: [{field, rule}]}
(grader.core.schemas.ErrorBody); bodies are checked by grader.web.bodies before any handler runs. A domain error
(grader.services.errors) raised for a page becomes that page's HTML answer instead (`page_error`, from grader.pages)."""

from __future__ import annotations

from collections.abc import Callable

from fastapi import FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, PlainTextResponse, Response
from fastapi.routing import iter_route_contexts
from starlette.exceptions import HTTPException as StarletteHTTPException

from grader.web.bodies import MAX_ERRORS, BodyGuard
from grader.web.headers import secure
from grader.services.errors import Conflict, DomainError, Forbidden, Invalid, NotFound, Refused

API_PREFIX = "/v1"


class ErrorWithFields(HTTPException):
    """An HTTPException whose body names the field and the rule, like a validation error."""

    def __init__(self, status_code: int, detail: str, errors: list[dict[str, str]], headers=None):
        super().__init__(status_code, detail, headers)
        self.errors = errors


def error(status: int, detail: str, errors: list[dict[str, str]] | None = None, headers=None) -> JSONResponse:
    errors = errors or []
    if len(errors) > MAX_ERRORS:  # a huge list of bad items must not make a huge answer
        detail = f"{detail} (the first {MAX_ERRORS} of {len(errors)} errors)"
        errors = errors[:MAX_ERRORS]
    return JSONResponse({"detail": detail, "errors": errors}, status_code=status, headers=headers)


def _field(loc: tuple) -> str:
    """A body field by its dotted path from the top (`sheet.answers.A3.agree`), a parameter as path.NAME / query.NAME."""
    parts = loc[1:] if len(loc) > 1 and loc[0] == "body" else loc
    return ".".join(str(p) for p in parts)


async def _validation(_: Request, exc: RequestValidationError) -> JSONResponse:
    errors = [{"field": _field(e["loc"]), "rule": e["msg"]} for e in exc.errors()]
    return error(422, "invalid request", errors)


async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
    headers = dict(getattr(exc, "headers", None) or {})
    if exc.status_code == 405:  # Starlette names only the first route of the path; a path has one route per method
        headers["Allow"] = ", ".join(sorted(_allowed_methods(request)))
    return error(exc.status_code, str(exc.detail), getattr(exc, "errors", None), headers=headers or None)


def _allowed_methods(request: Request) -> set[str]:
    methods: set[str] = set()
    for route in iter_route_contexts(request.app.routes):
        regex = getattr(route, "path_regex", None)
        if route.methods and regex is not None and regex.match(request.scope["path"]):
            methods |= route.methods
    return methods


def status_of(exc: DomainError) -> int:
    if isinstance(exc, Refused):
        return 429 if exc.retry_after_s is not None else 409
    for kind, code in ((NotFound, 404), (Forbidden, 403), (Conflict, 409), (Invalid, 422)):
        if isinstance(exc, kind):
            return code
    return 400


def retry_after(exc: DomainError) -> dict[str, str] | None:
    """Retry-After for a refusal that waiting lifts (a quota, an hourly limit), on the API's answer and a page's."""
    return {"Retry-After": str(exc.retry_after_s)} if isinstance(exc, Refused) and exc.retry_after_s else None


def with_retry_after(response: Response, exc: DomainError) -> Response:
    response.headers.update(retry_after(exc) or {})
    return response


def _domain_handler(page_error: Callable[[Request, DomainError, int], Response] | None):
    async def handle(request: Request, exc: DomainError) -> Response:
        code = status_of(exc)
        if page_error is not None and not request.url.path.startswith(API_PREFIX):
            return with_retry_after(page_error(request, exc, code), exc)
        return error(code, exc.detail, exc.errors, headers=retry_after(exc))
    return handle


async def _internal(request: Request, exc: Exception) -> Response:
    """A bug's 500 (Starlette's ServerErrorMiddleware logs the traceback): no detail of it, and the security headers
    every other answer has, since this one is sent outside the middleware that adds them."""
    if request.url.path.startswith(API_PREFIX):
        response: Response = error(500, "internal error; it was logged")
    else:
        response = PlainTextResponse("Internal error; it was logged. Try again, or tell the course staff.", 500)
    secure(response.headers, request.url.path)
    return response


def install(app: FastAPI, *, max_bytes: int, max_depth: int,
            page_error: Callable[[Request, DomainError, int], Response] | None = None) -> None:
    app.add_exception_handler(Exception, _internal)
    app.add_exception_handler(DomainError, _domain_handler(page_error))
    app.add_exception_handler(RequestValidationError, _validation)
    app.add_exception_handler(StarletteHTTPException, _http)
    app.add_middleware(BodyGuard, max_bytes=max_bytes, max_depth=max_depth)
