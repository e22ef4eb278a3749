"""Server-rendered pages (Jinja2 templates in grader/templates, assets in grader/static): sign-in and reports."""

from grader.pages.routes import router

__all__ = ["router"]
