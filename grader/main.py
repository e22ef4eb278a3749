"""Builds the FastAPI app: `uvicorn grader.main:app`. Never imports Genesis or torch."""

import re
from functools import partial
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

from grader.web import errors, logs
from grader.web.admission import BodyDeadline, ClientLimit, InFlightLimit, TrustedProxies, lifespan
from grader.web.fresh import FreshReads
from grader.web.headers import SecurityHeaders, docs_policy
from grader.api.main import api_router
from grader.api.routes.health import metrics_router
from grader.pages import errors as page_errors
from grader.pages.lti import launch as lti_pages
from grader.pages import router as pages_router
from grader.pages.templates import TEMPLATES
from grader.services.errors import DomainError
from grader.core.settings import settings

app = FastAPI(
    title="Genesis lab autograder",
    version="1",
    description="Submit a prediction sheet with case configs; workers measure the cases on real Genesis; "
    "the grade, every measured number and its provenance are stored and served. "
    "Every endpoint except /v1/health and the docs needs a bearer token.",
    lifespan=partial(lifespan, threads=settings.api_threads),
    docs_url=None,  # served below from grader/static, not a CDN
    redoc_url=None,
)


def early_page_error(request: Request, exc: DomainError, code: int) -> HTMLResponse:
    """A page's refusal made before the app runs (slow body, too many requests): no database, so no user named."""
    return TEMPLATES.TemplateResponse(request, "error.html", {"user": None, "error": exc, "code": code},
                                      status_code=code)


@app.get("/docs", include_in_schema=False)
def swagger_ui() -> HTMLResponse:
    page = get_swagger_ui_html(openapi_url=app.openapi_url, title=f"{app.title} - docs",
                               swagger_js_url="/static/swagger-ui-bundle.js", swagger_css_url="/static/swagger-ui.css",
                               swagger_favicon_url="/static/swagger-favicon.png",
                               swagger_ui_parameters={"validatorUrl": None})  # no badge fetched from swagger.io
    inline = re.search(r"<script>(.*?)</script>", page.body.decode(), re.S).group(1)
    page.headers["Content-Security-Policy"] = docs_policy(inline)
    return page


logs.install()  # no sign-in link's secret in the access log, whichever server runs the app

# Outermost last: the client's address (forwarded only by a trusted proxy); headers on every answer; then the
# per-client cap; then the whole body within its deadline; only then an admission slot; then the 304 from memory;
# then grader.web.errors' BodyGuard checks the body.
errors.install(app, max_bytes=settings.max_body_bytes, max_depth=settings.max_json_depth, page_error=page_errors.page_error)
page_errors.install(app)
# Innermost of these: a conditional read of an unchanged complete report answered 304 from the validator store,
# before any dependency opens a database session (grader.web.fresh); admitted, limited and marked like any answer.
app.add_middleware(FreshReads)
app.add_middleware(InFlightLimit, limit=settings.api_threads)
app.add_middleware(BodyDeadline, deadline_s=settings.body_deadline_s, max_bytes=settings.max_body_bytes,
                   page_error=early_page_error)
app.add_middleware(ClientLimit, limit=lambda: settings.client_max_in_flight, page_error=early_page_error)
app.add_middleware(SecurityHeaders)
app.add_middleware(TrustedProxies, trusted=lambda: settings.forwarded_allow_ips)
app.include_router(api_router)
app.include_router(metrics_router)
app.include_router(pages_router)
app.include_router(lti_pages.router)  # outside the pages' origin check: a launch is a cross-site POST by design
app.mount("/static", StaticFiles(directory=Path(__file__).resolve().parent / "static"), name="static")
