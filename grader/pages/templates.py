"""The pages' Jinja2 environment (grader/templates) and its filters."""

from __future__ import annotations

from pathlib import Path

from fastapi.templating import Jinja2Templates
from jinja2 import Environment, FileSystemLoader

from grader.core.timezones import local

TEMPLATES = Jinja2Templates(env=Environment(loader=FileSystemLoader(Path(__file__).resolve().parent.parent / "templates"),
                                             autoescape=True, extensions=["jinja2.ext.i18n"]))
# gettext in templates: `{{ _("text") }}`, `{% trans %}`. Until the catalogues are installed per request, the
# text is the English msgid itself.
TEMPLATES.env.install_null_translations(newstyle=True)


def local_time(at, user, seconds: bool = False) -> str:
    """A stored time as the signed-in user's course shows it: in the course's time zone, named."""
    return local(at, user.course.timezone if user else "UTC", seconds=seconds)


TEMPLATES.env.filters["local"] = local_time
