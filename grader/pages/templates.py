"""The pages' Jinja2 environment (grader/templates), its filters, and each request's language (grader.i18n).

The locale is chosen per request (the switch's cookie, else Accept-Language, else English) and its gettext is
passed in the template's context by a context processor: the shared environment is never changed per request, so
two requests in two languages on two threads cannot see each other's language.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

from fastapi import Request
from fastapi.templating import Jinja2Templates
from jinja2 import Environment, FileSystemLoader, pass_context
from jinja2.ext import _make_new_gettext, _make_new_ngettext  # jinja2's own newstyle wrappers (autoescape, %)

from grader import i18n


def request_locale(request: Request) -> str:
    """The request's language, chosen once and kept on request.state.locale."""
    locale = getattr(request.state, "locale", None)
    if locale is None:
        locale = i18n.choose(request.cookies.get(i18n.COOKIE), request.headers.get("accept-language"))
        request.state.locale = locale
    return locale


def _language(request: Request) -> dict:
    """Every template's gettext, in the request's language, and what the language switch needs."""
    locale = request_locale(request)
    gettext = _make_new_gettext(partial(i18n.gettext, locale))
    return {"locale": locale, "locales": i18n.NAMES, "_": gettext, "gettext": gettext,
            "ngettext": _make_new_ngettext(partial(i18n.ngettext, locale)),
            "here": request.url.path + (f"?{request.url.query}" if request.url.query else "")}


TEMPLATES = Jinja2Templates(env=Environment(loader=FileSystemLoader(Path(__file__).resolve().parent.parent / "templates"),
                                             autoescape=True, extensions=["jinja2.ext.i18n"]),
                            context_processors=[_language])
# Outside a request's context (none today) the text is the English msgid itself.
TEMPLATES.env.install_null_translations(newstyle=True)


def _locale(context) -> str:
    return context.get("locale") or i18n.DEFAULT


@pass_context
def local_time(context, at, user, seconds: bool = False) -> str:
    """A stored time as the signed-in user's course shows it: in the course's time zone, named, in the locale."""
    return i18n.local_time(at, user.course.timezone if user else "UTC", _locale(context), seconds=seconds)


@pass_context
def number(context, value) -> str:
    return i18n.number(value, _locale(context))


@pass_context
def percent(context, fraction) -> str:
    return i18n.percent(fraction, _locale(context))


@pass_context
def message(context, text) -> str:
    """A message a service built (a refusal, a lateness, a notice) in the page's language."""
    return i18n.message(_locale(context), text)


def _lesson(context, of: str | None = None) -> tuple[str, ...]:
    """The lesson whose texts the page shows: `of` where a page shows several (the dashboard's item analysis of each
    lesson), else the page's `lesson` (an assignment's, a submission's), else i18n's default."""
    name = of or context.get("lesson")
    return (name,) if isinstance(name, str) and name else ()


@pass_context
def lesson(context, text, section: str = "questions", of: str | None = None) -> str:
    """The lesson's own text (a question, a config rule, an answer label or choice) in the page's language; `of`
    names the lesson where the page shows more than one."""
    return i18n.lesson_word(_locale(context), section, text, *_lesson(context, of))


@pass_context
def answer(context, text) -> str:
    """A student's stored answer to an item in the form's words, in the page's language."""
    return i18n.answer(_locale(context), text, *_lesson(context))


@pass_context
def expected(context, text) -> str:
    """An item's expected answer, as a scoring rule stated it, in the form's words and the page's language."""
    return i18n.expected(_locale(context), text, *_lesson(context))


TEMPLATES.env.filters.update(local=local_time, num=number, pct=percent, msg=message, lesson=lesson, answer=answer,
                             expected=expected)
