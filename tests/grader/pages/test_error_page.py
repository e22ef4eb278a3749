"""The refusal page (grader.pages.errors, templates/error.html and _refusal.html) in the reader's words: a refusal
the service explained as data (grader.services.errors reason and facts, set by grader.services.setup.assignments.admit)
names the assignment by its title, writes its times as the page writes dates, counts with plural forms, and is shown
once; fields by their labels, not the API's names. The API keeps the service's English rule."""

from __future__ import annotations

import re

from sqlalchemy import select
from starlette.requests import Request

from grader.core.db import new_session
from grader.core.models import Assignment, User, utcnow
from grader.pages.errors import page_error
from grader.services.errors import Invalid, Refused
from grader.services.setup import assignments
from tests.grader.services.setup.test_assignments import at, create

ISO = re.compile(r"\d{4}-\d\d-\d\dT\d")


def request(language: str) -> Request:
    return Request({"type": "http", "method": "GET", "scheme": "http", "server": ("testserver", 80), "path": "/x",
                    "query_string": b"", "headers": [(b"accept-language", language.encode())]})


def refusal(assignment_id: int) -> Refused:
    with new_session() as session:
        try:
            assignments.admit(session=session, assignment=session.get(Assignment, assignment_id),
                              student=session.scalar(select(User).where(User.name == "alice")), now=utcnow())
        except Refused as exc:
            return exc
    raise AssertionError("admitted")


def shown(exc, language: str = "en") -> str:
    page = page_error(request(language), exc, 409).body.decode()
    return re.sub(r"\s+", " ", page.split("<main", 1)[1])


def test_a_refusal_names_the_assignment_by_title_with_local_times_and_plural_forms_once(api):
    soon = create(api, title="Week 3 concepts", open_at=at(1), due_at=at(2), hard_close_at=at(3)).json()["id"]
    page = shown(refusal(soon))
    assert "<h1>Submission refused</h1>" in page and "“Week 3 concepts” opens at " in page and "; it is now " in page
    assert f"assignment {soon}" not in page and "assignment_id" not in page and not ISO.search(page)
    assert page.count("opens at") == 1  # the message once, not again as a field's rule
    assert "“Week 3 concepts”于 " in shown(refusal(soon), "zh-CN") and "年" in shown(refusal(soon), "zh-CN")
    # The API's words stay the service's English rule, by the field's API name.
    assert re.search(rf"^assignment {soon} opens at {ISO.pattern}", refusal(soon).rule)

    one = create(api, title="Quiz", max_attempts=1).json()["id"]
    with new_session() as session:  # an attempt already used, as a submission leaves it
        from tests.factories import reference_sheet
        from grader.services.submissions import submit as submissions

        alice = session.scalar(select(User).where(User.name == "alice"))
        made = submissions.create_submission(session=session, student=alice, lesson="L03", sheet=reference_sheet(),
                                             specs=[], force_rerun=False)
        made.assignment_id, made.attempt = one, 1
        session.commit()
    page = shown(refusal(one))
    assert "“Quiz” allows 1 attempt, and you have used 1." in page and "1 attempts" not in page


def test_a_field_is_named_by_its_label_and_a_rule_repeating_the_detail_is_not_shown_twice(api):
    page = shown(Invalid("invalid sheet", [{"field": "sheet", "rule": "must be UTF-8 text"},
                                           {"field": "", "rule": "invalid sheet"}]))
    assert "prediction sheet: must be UTF-8 text" in page and "<code>sheet</code>" not in page
    assert page.count("invalid sheet") == 1
