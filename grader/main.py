"""Builds the FastAPI app: `uvicorn grader.main:app`. Never imports Genesis or torch."""

from functools import partial
from pathlib import Path

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from grader.api import errors
from grader.api.admission import InFlightLimit, lifespan
from grader.api.main import api_router
from grader.api.routes.health import metrics_router
from grader.pages import errors as page_errors
from grader.pages import router as pages_router
from grader.settings import settings

app = FastAPI(
    title="L03 simulation autograder",
    version="1",
    description="Submit a prediction sheet with case configs; workers measure the cases on real Genesis; "
    "the grade, every measured number and its provenance are stored and served. "
    "Every endpoint except /v1/health and the docs needs a bearer token.",
    lifespan=partial(lifespan, threads=settings.api_threads),
)
errors.install(app, max_bytes=settings.max_body_bytes, max_depth=settings.max_json_depth, page_error=page_errors.page_error)
page_errors.install(app)
app.add_middleware(InFlightLimit, limit=settings.api_threads)
app.include_router(api_router)
app.include_router(metrics_router)
app.include_router(pages_router)
app.mount("/static", StaticFiles(directory=Path(__file__).resolve().parent / "static"), name="static")
