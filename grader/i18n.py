"""The pages' languages: English (the msgids themselves) and Chinese, through Babel's gettext catalogues in
grader/translations, the lesson's question text from a translations file beside the rubric (rubric/lessons/
L03.zh.yaml), and numbers and dates in the reader's locale.

Nothing here changes what is stored or graded: a page translates what it shows, after the services decided it.
The API (/v1) stays English. Re-extract and update the catalogues with `make i18n` (docs/operator.md).

Catalogues are compiled from the .po in memory on first use (no .mo in the repository): a .mo beside its .po goes
stale the moment someone edits the .po and forgets to compile, and the page would then silently show English.
"""

from __future__ import annotations

import ast
import functools
import json
import re
from datetime import UTC, datetime
from gettext import NullTranslations
from io import BytesIO
from pathlib import Path

import yaml
from babel import negotiate_locale
from babel.dates import format_date, format_time
from babel.messages.mofile import write_mo
from babel.messages.pofile import read_po
from babel.numbers import format_decimal, format_percent
from babel.support import Translations

from grader.core.timezones import local, zone
from rubric.rubrics import lesson_folder

LOCALES = ("en", "zh")
DEFAULT = "en"
NAMES = {"en": "English", "zh": "中文"}
# The explicit switch (POST /language) wins over the browser's Accept-Language.
COOKIE = "grader_lang"
TRANSLATIONS_DIR = Path(__file__).resolve().parent / "translations"
DOMAIN = "messages"


def N_(text: str) -> str:
    """Marks a msgid for extraction (`make i18n`) where the text is translated later, on the page."""
    return text


# --- choosing the locale --------------------------------------------------------------------------------------------

def accepted(header: str | None) -> list[str]:
    """An Accept-Language header's tags, most preferred first (q=0 means "not this one")."""
    tags = []
    for n, part in enumerate((header or "").split(",")):
        tag, _, params = part.strip().partition(";")
        q = 1.0
        for param in params.split(";"):
            name, _, value = param.strip().partition("=")
            if name == "q":
                try:
                    q = float(value)
                except ValueError:
                    q = 0.0
        if tag and tag != "*" and q > 0:
            tags.append((-q, n, tag))
    return [tag for _, _, tag in sorted(tags)]


def choose(cookie: str | None, accept_language: str | None) -> str:
    """The explicit switch, else the browser's best language we have (zh-CN, zh-Hans-CN... -> zh), else English."""
    if cookie in LOCALES:
        return cookie
    return negotiate_locale(accepted(accept_language), LOCALES, sep="-") or DEFAULT


# --- catalogues -----------------------------------------------------------------------------------------------------

def po_path(locale: str) -> Path:
    return TRANSLATIONS_DIR / locale / "LC_MESSAGES" / f"{DOMAIN}.po"


@functools.lru_cache(maxsize=len(LOCALES))
def translations(locale: str) -> NullTranslations:
    """The locale's catalogue, compiled from its .po once per process; fuzzy entries are left out (English shows)."""
    if locale == DEFAULT or not po_path(locale).is_file():
        return NullTranslations()
    with po_path(locale).open("rb") as f:
        catalog = read_po(f, locale=locale, domain=DOMAIN)
    compiled = BytesIO()
    write_mo(compiled, catalog, use_fuzzy=False)
    compiled.seek(0)
    return Translations(compiled, domain=DOMAIN)


def known(locale: str) -> frozenset[str]:
    """The msgids the locale's catalogue translates."""
    t = translations(locale)
    keys = getattr(t, "_catalog", {})  # a plural entry is keyed (msgid, index)
    return frozenset(k if isinstance(k, str) else k[0] for k in keys if k and (isinstance(k, str) or k[1] == 0))


# Msgids a page asked a locale for that its catalogue lacks: what the tests walk the pages for. Bounded, since a
# dynamic message (a service's f-string no pattern matched) would otherwise grow it without end.
MISSING: set[tuple[str, str]] = set()
MISSING_LIMIT = 1000


def gettext(locale: str, message: str) -> str:
    if locale == DEFAULT or not message:
        return message
    t = translations(locale)
    if message not in known(locale) and len(MISSING) < MISSING_LIMIT:
        MISSING.add((locale, message))
    return t.gettext(message)


def ngettext(locale: str, singular: str, plural: str, n: int) -> str:
    if locale == DEFAULT:
        return singular if n == 1 else plural
    if singular not in known(locale) and len(MISSING) < MISSING_LIMIT:
        MISSING.add((locale, singular))
    return translations(locale).ngettext(singular, plural, n)


# --- messages the services build (English, with values) -------------------------------------------------------------

# Each pattern matches one message a service or a page route builds with values in it (the module is named); its
# msgid is translated and the matched values put back, themselves translated where they are messages too. A
# message no pattern matches shows in English (and is recorded in MISSING).
PATTERNS: list[tuple[re.Pattern, str]] = [
    # grader.services.setup.assignments.late_text
    (re.compile(r"^(?P<span>[0-9dhmins ]+) late \((?P<days>[0-9]+) days? charged\)$"),
     N_("%(span)s late (%(days)s days charged)")),
    # grader.services.setup.assignments.admit
    (re.compile(r"^assignment (?P<id>[0-9]+) opens at (?P<at>\S+(?: \(\S+\))?); it is (?P<now>\S+(?: \(\S+\))?)$"),
     N_("assignment %(id)s opens at %(at)s; it is %(now)s")),
    (re.compile(r"^assignment (?P<id>[0-9]+) closed at (?P<at>\S+(?: \(\S+\))?) \(its hard close\); "
                r"it is (?P<now>\S+(?: \(\S+\))?)$"),
     N_("assignment %(id)s closed at %(at)s (its hard close); it is %(now)s")),
    (re.compile(r"^assignment (?P<id>[0-9]+) closed at (?P<at>\S+(?: \(\S+\))?) \(your extension's hard close\); "
                r"it is (?P<now>\S+(?: \(\S+\))?)$"),
     N_("assignment %(id)s closed at %(at)s (your extension's hard close); it is %(now)s")),
    (re.compile(r"^assignment (?P<id>[0-9]+) allows (?P<n>[0-9]+) attempts?; (?P<used>[0-9]+) already submitted$"),
     N_("assignment %(id)s allows %(n)s attempts; %(used)s already submitted")),
    (re.compile(r"^assignment (?P<id>[0-9]+) allows (?P<n>[0-9]+) submissions? per hour; (?P<k>[0-9]+) in the last "
                r"hour, the next is allowed at (?P<at>\S+(?: \(\S+\))?)$"),
     N_("assignment %(id)s allows %(n)s submissions per hour; %(k)s in the last hour, the next is allowed at %(at)s")),
    # grader.services.identity.sign_in_links.refusal
    (re.compile(r"^This sign-in link was already used, at (?P<at>.+); a link works once\. Ask your instructor for a "
                r"new one if you are not signed in\.$"),
     N_("This sign-in link was already used, at %(at)s; a link works once. Ask your instructor for a new one if you "
        "are not signed in.")),
    (re.compile(r"^This sign-in link was revoked at (?P<at>.+): a newer link was issued, or your access was "
                r"withdrawn\. Use the newest link you were sent, or ask your instructor\.$"),
     N_("This sign-in link was revoked at %(at)s: a newer link was issued, or your access was withdrawn. Use the "
        "newest link you were sent, or ask your instructor.")),
    (re.compile(r"^This sign-in link expired at (?P<at>.+)\. Ask your instructor for a new one\.$"),
     N_("This sign-in link expired at %(at)s. Ask your instructor for a new one.")),
    # grader.services.submissions.visibility (why scores are not shown yet)
    (re.compile(r"^scores and feedback are (?P<why>.+)$"), N_("scores and feedback are %(why)s")),
    (re.compile(r"^some items' scores and feedback are (?P<why>.+)$"),
     N_("some items' scores and feedback are %(why)s")),
    (re.compile(r"^(?P<p>[0-9.]+) of (?P<m>[0-9.]+) points pending \((?P<ids>[A-Z0-9, ]+)\): (?P<why>.+)$"),
     N_("%(p)s of %(m)s points pending (%(ids)s): %(why)s")),
    (re.compile(r"^shown after the due date, (?P<at>.+)$"), N_("shown after the due date, %(at)s")),
    (re.compile(r"^shown once “(?P<title>.+)” is released by an instructor$"),
     N_("shown once “%(title)s” is released by an instructor")),
    (re.compile(r"^withheld: (?P<why>.+)$"), N_("withheld: %(why)s")),
    # rubric.one_factor (the one-factor verdict of a config, on the form and the report)
    (re.compile(r"^(?P<role>\S+) vs (?P<base>\S+): one factor \((?P<changed>.*?)\)"
                r"(?P<note>; visual only, not a physical input: .+)?$"),
     N_("%(role)s vs %(base)s: one factor (%(changed)s)%(note)s")),
    (re.compile(r"^(?P<role>\S+) vs (?P<base>\S+): too many inputs changed at once; only (?P<may>.+?) may change, "
                r"but also: (?P<also>.+?)(?P<note>; visual only, not a physical input: .+)?$"),
     N_("%(role)s vs %(base)s: too many inputs changed at once; only %(may)s may change, but also: %(also)s%(note)s")),
    (re.compile(r"^; visual only, not a physical input: (?P<fields>.+)$"),
     N_("; visual only, not a physical input: %(fields)s")),
    # grader.pages.submissions.sheet_form notices
    (re.compile(r"^The draft now holds your submission (?P<id>[0-9]+)'s sheet\.$"),
     N_("The draft now holds your submission %(id)s's sheet.")),
    (re.compile(r"^Imported (?P<file>.+) into the draft; check it before submitting\.$"),
     N_("Imported %(file)s into the draft; check it before submitting.")),
]
# Words the pages show from stored values (states, roles, parts, verdicts, kinds), translated where shown.
WORDS = [
    N_("queued"), N_("running"), N_("grading"), N_("graded"), N_("failed"), N_("done"),
    N_("student"), N_("instructor"), N_("auditor"), N_("checkpoints"), N_("exercises"), N_("sheet"),
    N_("latest"), N_("best"), N_("computed"), N_("measured"), N_("conceptual"), N_("config"),
    N_("contact"), N_("friction"), N_("ok"), N_("invalid"), N_("timeout"),
    # grader.pages.views.VERDICT_LABEL
    N_("credit"), N_("no credit"), N_("inconclusive (not counted)"), N_("config fault"), N_("not measured"),
    N_("pending"),
    # grader.pages.submissions.report.PART_TITLES
    N_("Part A: contact and time step"), N_("Part B: friction and stopping distance"), N_("Concept checkpoints"),
    N_("Hands-on exercise"), N_("Extension"),
]
# Whole messages without values, from the services and page routes (translated as they are).
MESSAGES = [
    N_("on time"), N_("Draft saved."), N_("The sheet passes every rule a submission checks."),
    N_("That token is unknown or has been revoked."), N_("submission refused"), N_("invalid sheet"),
    N_("invalid YAML"), N_("unknown assignment"), N_("cross-site request refused"),
    N_("This sign-in link is unknown. Check that the whole link was copied, or ask your instructor for a new one."),
    N_("must be UTF-8 text"), N_("the file"), N_("invalid notebook"),
    # rubric.scoring: the expected answers stated in words (grader.i18n.expected)
    N_("no: also require clearance above tolerance"), N_("no: read proxy, contact, clearance and trajectory together"),
    N_("no: the hold interval must stay below threshold"), N_("false: improvement is not guaranteed"),
    N_("the measured sustained stops"), N_("unchanged within tolerance"),
    N_("the lane with the longer sustained-stop distance"), N_("lanes whose stop distance changes within tolerance"),
    N_("the direction measured at fixed dt"), N_("a one-factor config"), N_("a measured result"),
    N_("no listed rule fits the engine"), N_("a change that no answer names"), N_("unresolved"),
    # rubric.metrics.TUMBLE_EXPLANATION
    N_("A cube that tipped over onto another face travelled partly by tumbling, not sliding, so its stop distance is "
       "not a sliding stop and cannot be compared with friction alone."),
]


def message(locale: str, text: str | None) -> str:
    """A message a service or route built, in the locale: the catalogue's text, a pattern's, or the English."""
    if text is None or locale == DEFAULT:
        return text or ""
    if text in known(locale):
        return translations(locale).gettext(text)
    for pattern, msgid in PATTERNS:
        found = pattern.match(text)
        if found:
            values = {k: _value(locale, k, v) for k, v in found.groupdict().items()}
            try:
                if msgid in known(locale):
                    return translations(locale).gettext(msgid) % values
            except (KeyError, ValueError, TypeError):  # a translation that lost a placeholder: the English, not a 500
                pass
            MISSING.add((locale, msgid))
            return text
    return gettext(locale, text)


def _value(locale: str, key: str, value: str | None) -> str:
    """A value matched in a message, put back into its translation: reasons and notes are messages themselves."""
    if value is None:
        return ""
    if key == "why":
        return _reasons(locale, value)
    if key == "note":
        return message(locale, value)
    return gettext(locale, value) if value == "nothing" else value


def _reasons(locale: str, text: str) -> str:
    """Reasons a service joined with " and " or "; ", each translated, joined the locale's way."""
    joined = []
    for group in text.split("; "):
        joined.append(gettext(locale, N_(" and ")).join(message(locale, part) for part in group.split(" and ")))
    return gettext(locale, N_("; ")).join(joined)


# --- the lesson's own text (question text, config rules, answer labels and choices) ----------------------------------

@functools.lru_cache(maxsize=8)
def lesson_text(lesson: str, locale: str) -> dict[str, dict[str, str]]:
    """The translations file beside the lesson's rubric (`L03.zh.yaml`), keyed by the English text exactly as the
    rubric says it: a published version's content is never touched, and a changed question shows in English until
    its translation is added."""
    folder = lesson_folder(lesson)
    path = folder / f"{lesson}.{locale}.yaml" if folder else None
    if locale == DEFAULT or path is None or not path.is_file():
        return {}
    data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    return {section: dict(entries or {}) for section, entries in data.items() if section != "lesson"}


def lesson_word(locale: str, section: str, text: str, lesson: str = "L03") -> str:
    """`text` of the lesson (a question, a config rule, an answer label or choice) in the locale, else as it is."""
    if locale == DEFAULT or not text:
        return text
    found = lesson_text(lesson, locale).get(section, {}).get(text)
    if found is None and len(MISSING) < MISSING_LIMIT:
        MISSING.add((locale, f"{lesson}:{section}:{text}"))
    return found or text


def choice_word(locale: str, value, lesson: str = "L03") -> str:
    """One answer value as the form shows its choice: an id with spaces (`unequal simulated duration`), yes/no for a
    boolean, in the locale through the lesson's choices; a number as the locale writes it; free text as it is."""
    if isinstance(value, bool):
        return lesson_word(locale, "choices", str(value).lower(), lesson) if locale != DEFAULT else ("yes" if value else "no")
    if isinstance(value, int | float):
        return number(value, locale)
    text = str(value)
    if text in ("true", "false"):  # a boolean the scoring rule wrote as text
        return choice_word(locale, text == "true", lesson)
    spaced = text.replace("_", " ")
    if locale == DEFAULT:
        return spaced if re.fullmatch(r"[a-z_]+", text) else text
    found = lesson_text(lesson, locale).get("choices", {}).get(spaced)
    return found or (gettext(locale, spaced) if spaced in known(locale) else text)


def _answer_parts(locale: str, value, label: str, lesson: str) -> list[tuple[str, str]]:
    """(label, value) pairs of one answer, nested answers flattened into the form's labels ("baseline low")."""
    if isinstance(value, dict) and set(value) == {"value", "unit"}:
        return [(label, f"{number(value['value'], locale)} {value['unit']}")]
    if isinstance(value, dict) and set(value) == {"kind"}:
        return [(label, choice_word(locale, value["kind"], lesson))]
    if isinstance(value, dict):
        return [pair for key, item in value.items()
                for pair in _answer_parts(locale, item, " ".join(p for p in (label, key.replace("_", " ")) if p), lesson)]
    if isinstance(value, list):
        return [(label, gettext(locale, N_(", ")).join(choice_word(locale, v, lesson) for v in value)
                 or gettext(locale, N_("none")))]
    return [(label, choice_word(locale, value, lesson))]


def answer(locale: str, value, lesson: str = "L03") -> str:
    """A student's answer to one item (the sheet's answer, as stored in the grade's JSON) in the form's words:
    'direction: decrease', '方向：减小'; each field by its form label, each value by its choice."""
    if isinstance(value, str):
        try:
            value = json.loads(value)
        except ValueError:
            return value
    parts = _answer_parts(locale, value, "", lesson)
    colon, semicolon = gettext(locale, N_(": ")), gettext(locale, N_("; "))
    return semicolon.join(f"{lesson_word(locale, 'labels', label, lesson)}{colon}{text}" if label else text
                          for label, text in parts)


# The expected answers the scoring rules state (rubric/scoring), each as a pattern whose values are answer values:
# put in the reader's words by `expected`. An expected text none of them matches is a choice or shows as it is.
EXPECTED: list[tuple[re.Pattern, str]] = [
    (re.compile(r"^(?P<field>agree|same_length)=(?P<value>True|False)$"), "field"),
    (re.compile(r"^(?P<many>[0-9]+) samples: (?P<a>\[.*?\]), (?P<few>[0-9]+) samples: (?P<b>\[.*?\])$"), "samples"),
    (re.compile(r"^lanes (?P<value>\[.*\])$"), "lanes"),
    (re.compile(r"^visual layer; affects results: (?P<value>true|false)$"), "layer"),
    (re.compile(r"^measured (?P<value>[a-z_]+)$"), "measured"),
    (re.compile(r"^the lane measured farther \((?P<value>[a-z_]+)\)$"), "farther"),
    (re.compile(r"^only diagnostics measured to improve: (?P<value>\[.*\]|none)$"), "improve"),
    (re.compile(r"^substep_dt (?P<dt>[0-9.e-]+) s, (?P<n>[0-9]+) samples, (?P<u>[0-9]+) internal updates$"), "timing"),
    (re.compile(r"^\{.*\}$"), "mapping"),
]


def expected(locale: str, text: str | None, lesson: str = "L03") -> str:
    """The expected answer a scoring rule stated, in the reader's words, with the same translations the form uses."""
    if not text:
        return text or ""
    for pattern, form in EXPECTED:
        found = pattern.match(text)
        if not found:
            continue
        try:
            return _expected(locale, form, found, text, lesson)
        except (ValueError, SyntaxError):  # not the shape the pattern promised: shown as it is
            return text
    if " or " in text and all(re.fullmatch(r"[a-z_]+", part) for part in text.split(" or ")):
        return gettext(locale, N_(" or ")).join(choice_word(locale, part, lesson) for part in text.split(" or "))
    if re.fullmatch(r"[a-z_]+", text):
        return choice_word(locale, text, lesson)
    return message(locale, text)


def _expected(locale: str, form: str, found: re.Match, text: str, lesson: str) -> str:
    values = found.groupdict()
    if form == "field":
        return answer(locale, {values["field"]: values["value"] == "True"}, lesson)
    if form == "samples":
        return answer(locale, {f"samples {values['many']}": ast.literal_eval(values["a"]),
                               f"samples {values['few']}": ast.literal_eval(values["b"])}, lesson)
    if form == "lanes":
        return answer(locale, {"lanes": ast.literal_eval(values["value"])}, lesson)
    if form == "layer":
        return answer(locale, {"color_layer": "visual", "affects_results": values["value"] == "true"}, lesson)
    if form == "measured":
        return gettext(locale, N_("measured %(value)s")) % {"value": choice_word(locale, values["value"], lesson)}
    if form == "farther":
        return gettext(locale, N_("the lane measured farther (%(value)s)")) % {
            "value": choice_word(locale, values["value"], lesson)}
    if form == "improve":
        improved = [] if values["value"] == "none" else ast.literal_eval(values["value"])
        return gettext(locale, N_("only diagnostics measured to improve: %(value)s")) % {
            "value": answer(locale, improved, lesson)}
    if form == "timing":
        return answer(locale, {"substep_dt": {"value": float(values["dt"]), "unit": "s"}, "samples": int(values["n"]),
                               "internal_updates": int(values["u"])}, lesson)
    return answer(locale, ast.literal_eval(text), lesson)


# --- numbers and dates ----------------------------------------------------------------------------------------------

def babel_locale(locale: str) -> str:
    return {"zh": "zh_Hans_CN"}.get(locale, "en")


def local_time(at: datetime | None, timezone: str, locale: str, *, seconds: bool = False) -> str:
    """A stored time in the course's zone, as the locale writes dates: '2026-12-08 10:00 CET', '2026年12月8日 10:00 CET'."""
    if at is None or locale == DEFAULT:
        return local(at, timezone, seconds=seconds)
    aware = (at if at.tzinfo is not None else at.replace(tzinfo=UTC)).astimezone(zone(timezone))
    when = format_time(aware, "HH:mm:ss" if seconds else "HH:mm", locale=babel_locale(locale))
    return f"{format_date(aware, 'medium', locale=babel_locale(locale))} {when} {aware.strftime('%Z')}"


def number(value, locale: str) -> str:
    """A score or a count as the locale writes numbers (no trailing zeros: 27.5, 30)."""
    if value is None:
        return "–"
    return format_decimal(value, format="#,##0.######", locale=babel_locale(locale))


def percent(fraction, locale: str) -> str:
    """0.1 -> '10%' as the locale writes percentages."""
    return format_percent(fraction, format="#,##0.##%", locale=babel_locale(locale))


# --- the catalogues' upkeep (`make i18n`) ---------------------------------------------------------------------------

def untranslated(locale: str) -> list[str]:
    """The msgids of the extracted template (messages.pot) that the locale's catalogue does not translate (absent,
    empty or fuzzy): what a translator still has to do."""
    with (TRANSLATIONS_DIR / f"{DOMAIN}.pot").open("rb") as f:
        template = read_po(f)
    with (TRANSLATIONS_DIR / locale / "LC_MESSAGES" / f"{DOMAIN}.po").open("rb") as f:
        catalog = read_po(f)

    def done(message) -> bool:  # every form filled (a plural's too: compiling fills an empty one with the msgid)
        strings = message.string if isinstance(message.string, tuple) else (message.string,)
        return not message.fuzzy and all(strings)

    return sorted(str(m.id) for m in template if m.id and not ((t := catalog.get(m.id)) is not None and done(t)))


def main() -> int:
    """`python -m grader.i18n`: what each locale's catalogue still lacks; exit status 1 when anything does."""
    translations.cache_clear()
    missing = {locale: untranslated(locale) for locale in LOCALES if locale != DEFAULT}
    for locale, ids in missing.items():
        print(f"{locale}: {len(ids)} untranslated")
        for msgid in ids:
            print(f"  {msgid!r}")
    return 1 if any(missing.values()) else 0


if __name__ == "__main__":
    raise SystemExit(main())
