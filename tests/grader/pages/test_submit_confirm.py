"""The confirmation between the sheet form and a submission (grader.pages.submissions.sheet_form): it names the attempt, the
lateness and the penalty by the assignment's own rules, submits only the draft it showed, and a submission the rules
refuse names the rule beside the form and keeps the draft."""

from __future__ import annotations

import re
from datetime import timedelta

from grader.core.db import new_session
from grader.core.models import Submission, utcnow
from tests.grader.services.setup.test_assignments import at, checkpoint_sheet, create
from tests.grader.pages.test_sheet_form import form_fields


def checkpoint_form(api, aid: int, who: str = "alice") -> dict[str, list[str]]:
    """The assignment's form, filled with a valid checkpoint sheet through the YAML import."""
    import yaml

    from tests.grader.pages.test_sheet_form import import_yaml

    page = import_yaml(api, yaml.safe_dump(checkpoint_sheet(who)), path=f"/assignments/{aid}/sheet", who=who)
    assert page.status_code == 200, page.text
    return form_fields(page.text)


def submissions_of(who: str) -> list[Submission]:
    with new_session() as session:
        return [s for s in session.query(Submission).all() if s.student.name == who]


def press(api, aid: int, data: dict, who: str = "alice", **kw):
    return api.client.post(f"/assignments/{aid}/sheet", headers=api.as_(who), data=data, **kw)


def confirm_fields(page: str) -> dict[str, str]:
    form = page.split('id="confirm-form"', 1)[1].split("</form>", 1)[0]
    return dict(re.findall(r'name="(\w+)" value="([^"]*)"', form))


def test_submitting_first_shows_the_attempt_lateness_and_penalty_then_submits_that_attempt(api):
    aid = create(api, open_at=at(-3), due_at=at(hours=-2.2), hard_close_at=at(3), late_penalty_per_day=0.1,
                 max_attempts=3).json()["id"]
    fields = checkpoint_form(api, aid)
    shown = press(api, aid, {**fields, "action": "submit"})
    assert shown.status_code == 200, shown.text
    assert submissions_of("alice") == [], "the confirmation stores nothing"
    text = shown.text
    assert "Submit attempt 1 of Checkpoints?" in text
    assert re.search(r'id="confirm-attempt">attempt 1 of 3 \(2 left after this one\)<', text)
    assert re.search(r'id="confirm-late">2 h 1[12] min late \(1 day charged\)<', text), text
    assert 'id="confirm-penalty">10% of this attempt\'s score is taken<' in text
    assert '>Submit attempt 1</button>' in text and f'href="/assignments/{aid}/sheet" id="confirm-back"' in text
    assert "style=" not in text and "<script" not in text.split("</head>")[1]
    # Back to the form: the draft is as it was typed.
    back = api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert form_fields(back.text) == fields
    done = press(api, aid, confirm_fields(text), follow_redirects=False)
    assert done.status_code == 303, done.text
    (stored,) = submissions_of("alice")
    assert done.headers["location"] == f"/submissions/{stored.id}/progress"
    assert stored.attempt == 1 and 2 * 3600 < stored.late_seconds < 3 * 3600
    assert stored.sheet == checkpoint_sheet("alice") | {"lesson": stored.lesson}
    # The next confirmation names the next attempt.
    again = press(api, aid, {**fields, "action": "submit"})
    assert "Submit attempt 2 of Checkpoints?" in again.text and "attempt 2 of 3 (1 left after this one)" in again.text


def test_an_on_time_confirmation_says_so_and_a_free_sheet_has_no_attempt(api):
    aid = create(api).json()["id"]
    shown = press(api, aid, {**checkpoint_form(api, aid), "action": "submit"})
    assert 'id="confirm-late">on time<' in shown.text and "none: no late penalty applies" in shown.text
    assert "attempt 1 (no limit on attempts)" in shown.text
    import yaml

    from tests.factories import REFERENCE_YAML
    from tests.grader.pages.test_sheet_form import import_yaml

    page = import_yaml(api, REFERENCE_YAML.read_text())
    free = api.client.post("/sheet", headers=api.as_("alice"), data={**form_fields(page.text), "action": "submit"})
    assert free.status_code == 200 and "Submit your sheet outside any assignment?" in free.text
    assert "not counted as an attempt" in free.text
    done = api.client.post("/sheet", headers=api.as_("alice"), data=confirm_fields(free.text), follow_redirects=False)
    assert done.status_code == 303 and done.headers["location"].endswith("/progress")
    (stored,) = submissions_of("alice")
    assert stored.sheet == yaml.safe_load(REFERENCE_YAML.read_text()) and stored.attempt is None


def test_a_draft_changed_after_the_confirmation_is_confirmed_again_not_submitted(api):
    aid = create(api).json()["id"]
    fields = checkpoint_form(api, aid)
    shown = press(api, aid, {**fields, "action": "submit"})
    # Another tab saves a different answer before "Submit attempt 1" is pressed.
    api.client.post(f"/assignments/{aid}/sheet/draft", headers=api.as_("alice"),
                    data={**fields, "answers.C6.pair_rule": "min"})
    again = press(api, aid, confirm_fields(shown.text))
    assert again.status_code == 200 and "Your draft changed after this confirmation was shown" in again.text
    assert submissions_of("alice") == []
    done = press(api, aid, confirm_fields(again.text), follow_redirects=False)
    assert done.status_code == 303
    (stored,) = submissions_of("alice")
    assert stored.sheet["answers"]["C6"]["pair_rule"] == "min"


def test_a_confirmation_made_stale_by_another_submission_names_the_new_attempt(api):
    aid = create(api).json()["id"]
    fields = checkpoint_form(api, aid)
    first = press(api, aid, {**fields, "action": "submit"})
    second = press(api, aid, {**fields, "action": "submit"})
    assert press(api, aid, confirm_fields(second.text), follow_redirects=False).status_code == 303
    stale = press(api, aid, confirm_fields(first.text))
    assert "this one would now take the attempt named below" in stale.text
    assert ">Submit attempt 2</button>" in stale.text
    assert len(submissions_of("alice")) == 1


def _refusal(api, aid: int, fields: dict, rule: str, code: int) -> None:
    """Submit is refused before any confirmation: the rule beside the form, nothing stored, the draft kept."""
    before = len(submissions_of("alice"))
    refused = press(api, aid, {**fields, "answers.C6.pair_rule": "max", "action": "submit"})
    assert refused.status_code == code, refused.text
    assert 'id="check-summary"' in refused.text and "Your draft is kept." in refused.text
    # The rule once, at the top, in the reader's words: the assignment's title, not its number or the API's field
    # name, times in the course's zone as the page writes dates (no ISO 8601), counts with their plural forms.
    assert refused.text.count(rule) == 1, refused.text
    summary = refused.text.split('id="check-summary"', 1)[1].split("</div>", 1)[0]
    assert rule in summary and "Not submitted" in summary
    assert "assignment_id" not in refused.text and f"assignment {aid}" not in refused.text
    assert not re.search(r"[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:", refused.text)
    assert 'id="confirm-form"' not in refused.text
    assert len(submissions_of("alice")) == before
    kept = api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert 'name="answers.C6.pair_rule" value="max" checked' in kept.text


def test_not_open_yet_is_refused_with_the_opening_time(api):
    aid = create(api, open_at=at(1), due_at=at(2), hard_close_at=at(3)).json()["id"]
    _refusal(api, aid, checkpoint_form(api, aid), "“Checkpoints” opens at ", 409)


def test_after_the_hard_close_is_refused_with_the_close(api):
    aid = create(api, open_at=at(-3), due_at=at(-2), hard_close_at=at(-1)).json()["id"]
    _refusal(api, aid, checkpoint_form(api, aid), "“Checkpoints” closed at ", 409)


def test_the_attempt_limit_is_refused_naming_it(api):
    aid = create(api, max_attempts=1).json()["id"]
    fields = checkpoint_form(api, aid)
    shown = press(api, aid, {**fields, "action": "submit"})
    assert press(api, aid, confirm_fields(shown.text), follow_redirects=False).status_code == 303
    _refusal(api, aid, fields, "“Checkpoints” allows 1 attempt, and you have used 1.", 409)


def test_the_hourly_limit_is_refused_with_the_next_allowed_time(api):
    aid = create(api, max_per_hour=1).json()["id"]
    fields = checkpoint_form(api, aid)
    shown = press(api, aid, {**fields, "action": "submit"})
    assert press(api, aid, confirm_fields(shown.text), follow_redirects=False).status_code == 303
    _refusal(api, aid, fields, "“Checkpoints” takes 1 submission per hour from each student; the next is allowed at ",
             429)


def test_a_confirmation_outlived_by_the_hard_close_is_refused_at_submit_and_keeps_the_draft(api):
    """The rules are applied again when the confirmed draft is submitted: a close passed meanwhile refuses it."""
    aid = create(api, open_at=at(-3), due_at=at(-2), hard_close_at=at(hours=1)).json()["id"]
    fields = checkpoint_form(api, aid)
    shown = press(api, aid, {**fields, "action": "submit"})
    assert "Submit attempt 1" in shown.text
    with new_session() as session:
        from grader.core.models import Assignment

        session.get(Assignment, aid).hard_close_at = utcnow() - timedelta(minutes=1)
        session.commit()
    refused = press(api, aid, confirm_fields(shown.text))
    assert refused.status_code == 409 and refused.text.count("“Checkpoints” closed at ") == 1
    assert 'id="check-summary"' in refused.text and submissions_of("alice") == []
    assert form_fields(api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice")).text) == fields


def test_an_invalid_sheet_is_refused_before_the_confirmation(api):
    aid = create(api).json()["id"]
    fields = checkpoint_form(api, aid)
    refused = press(api, aid, {**fields, "answers.C5.pair_friction": "lots", "action": "submit"})
    assert refused.status_code == 422 and 'id="confirm-form"' not in refused.text
    assert 'id="err-answers.C5.pair_friction"' in refused.text and submissions_of("alice") == []


def test_another_site_cannot_confirm_a_submission(api):
    aid = create(api).json()["id"]
    shown = press(api, aid, {**checkpoint_form(api, aid), "action": "submit"})
    refused = api.client.post(f"/assignments/{aid}/sheet", data=confirm_fields(shown.text),
                              headers={**api.as_("alice"), "Sec-Fetch-Site": "cross-site"})
    assert refused.status_code == 403 and submissions_of("alice") == []


def test_a_one_factor_violation_is_repeated_on_the_confirmation_and_needs_a_second_tick(api):
    """Issue 33: the confirmation names the broken config and the items it voids; submitting it takes the tick
    "I submit knowing these items will be voided", whose absence refuses naming it, the draft kept."""
    from tests.factories import REFERENCE_YAML
    from tests.grader.pages.test_sheet_form import import_yaml

    page = import_yaml(api, REFERENCE_YAML.read_text())
    shown = api.client.post("/sheet", headers=api.as_("alice"), data={
        **form_fields(page.text, **{"configs.table_exercise.dt": "0.02"}), "action": "submit"})
    assert shown.status_code == 200, shown.text
    voids = shown.text.split('id="confirm-voids"', 1)[1].split("</div>", 1)[0]
    assert "table exercise vs friction-baseline: dt may not change (dt 0.01 → 0.02)." in voids
    assert "Every item that compares this config's run will be voided" in voids
    assert 'form="confirm-form" name="accept_voids" value="yes" required' in shown.text
    refused = api.client.post("/sheet", headers=api.as_("alice"), data=confirm_fields(shown.text))  # not ticked
    assert refused.status_code == 422 and 'id="err-accept_voids"' in refused.text
    assert '<a href="#accept-voids">I submit knowing these items will be voided</a>' in refused.text
    assert submissions_of("alice") == []
    assert 'value="0.02"' in api.client.get("/sheet", headers=api.as_("alice")).text  # the draft is kept
    done = api.client.post("/sheet", headers=api.as_("alice"), data={**confirm_fields(refused.text),
                                                                       "accept_voids": "yes"}, follow_redirects=False)
    assert done.status_code == 303, done.text
    (stored,) = submissions_of("alice")
    assert stored.sheet["configs"]["table_exercise"]["dt"] == 0.02


def test_a_confirmation_without_a_violation_asks_no_second_tick(api):
    aid = create(api, part="exercises").json()["id"]
    from tests.factories import REFERENCE_YAML
    from tests.grader.pages.test_sheet_form import import_yaml

    page = import_yaml(api, REFERENCE_YAML.read_text(), path=f"/assignments/{aid}/sheet")
    shown = press(api, aid, {**form_fields(page.text), "action": "submit"})
    assert shown.status_code == 200 and 'id="confirm-voids"' not in shown.text and "accept_voids" not in shown.text
