"""Plurals through the catalogue everywhere (issue 49: the course page said "1 submissions per hour"): every
pluralised message of the pages renders at 1 and at 2 in each language the course teaches in, with every placeholder
filled, and no message outside a plural puts a count before a plural noun. The services' own English messages say
"1 attempt" and "1 submission per hour" (test_a_services_message_says_one_in_the_singular)."""

from __future__ import annotations

import re

import pytest
from babel.messages.pofile import read_po

from grader import i18n

PLACEHOLDER = re.compile(r"%\((\w+)\)s")


def _template():
    with (i18n.TRANSLATIONS_DIR / f"{i18n.DOMAIN}.pot").open("rb") as f:
        return read_po(f)


PLURALS = [m.id for m in _template() if m.id and not isinstance(m.id, str)]


def test_the_catalogue_has_the_plurals_it_should():
    assert len(PLURALS) > 20  # the pages' counted messages; an extraction that lost them would pass the rest vacuously


@pytest.mark.parametrize("locale", i18n.LOCALES)
@pytest.mark.parametrize("ids", PLURALS, ids=lambda ids: ids[0][:60])
def test_each_plural_renders_at_one_and_two(locale, ids):
    singular, plural = ids
    names = set(PLACEHOLDER.findall(singular)) | set(PLACEHOLDER.findall(plural))
    values = {name: f"<{name}>" for name in names}
    for n in (1, 2):
        text = i18n.ngettext(locale, singular, plural, n) % (values | {"count": n, "num": n})
        assert "%(" not in text and text.strip(), (locale, n, text)
        if locale == i18n.DEFAULT:
            assert text == (singular if n == 1 else plural) % (values | {"count": n, "num": n})
        else:  # translated (Chinese has one form for both)
            assert text != (singular if n == 1 else plural) % (values | {"count": n, "num": n}), (locale, n, text)


# A count placed before a plural noun outside a plural message ("%(n)s submissions"), and the messages where that is
# right whatever the count (a unit: "%(n)s s"; a range; a count that is never 1).
COUNTED_NOUN = re.compile(r"%\((?:n|count|k|done|queued|running|failed)\)s (?:[a-z]+ )?(?:submissions|runs|items|cases|"
                          r"students|variants|attempts|points|fields|pages|members|days|hours|minutes|seconds)\b")


def test_no_message_outside_a_plural_counts_before_a_plural_noun():
    # A service's message is English text built in Python and matched by a pattern (grader.i18n.PATTERNS) to be
    # translated: its msgid is the translation's key, the English shown is the service's own (which says "1 attempt").
    keys = {msgid for _, msgid in i18n.PATTERNS}
    singular_only = [m.id for m in _template() if isinstance(m.id, str) and m.id not in keys
                     and COUNTED_NOUN.search(m.id)]
    assert not singular_only, "say these through {% pluralize %} / ngettext: " + "; ".join(singular_only)


def test_a_services_message_says_one_in_the_singular(api):
    """The refusal of a second attempt where one is allowed, in English and in Chinese (its pattern takes both)."""
    from tests.grader.services.setup.test_assignments import create, submit

    aid = create(api, max_attempts=1).json()["id"]
    assert submit(api, aid).status_code == 202
    refused = submit(api, aid)
    assert refused.status_code == 409, refused.text
    rule = refused.json()["errors"][0]["rule"]
    assert f"assignment {aid} allows 1 attempt; 1 already submitted" == rule, rule
    assert i18n.message("zh", rule) != rule
