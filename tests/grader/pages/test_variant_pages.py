"""A student's own lab on their pages (issue 34) on the in-process app: the course page and the sheet form state their
variant's parameters in English and Chinese, the questions name their numbers, the config editor starts from their
baseline and the one-factor check compares with it; staff and free sheets keep the lesson's; a student never sees
another variant's parameters. The pool's rows are built directly (the draw of seed 391, no Genesis needed to render a
page); the measured path is tests/integration/test_variant_pages_browser.py."""

from __future__ import annotations

import yaml
from markupsafe import escape
from sqlalchemy import select

import rubric
from rubric.scoring import SHEET_CASE_PREFIX
from rubric.variants import texts
from tests.factories import reference_sheet
from tests.grader.pages.test_sheet_form import form_fields, import_yaml
from tests.grader.services.setup.test_assignments import at, create

SEED, K = 391, 3
DROPPED, KEPT = "v391-1", ("v391-2", "v391-3")
ZH = {"Accept-Language": "zh-CN"}


def drawn() -> dict[str, rubric.Variant]:
    return {v.id: v for v in rubric.draw_pool(rubric.load_variant_space("L03", "1"), seed=SEED, k=K).variants}


def pooled_assignment(api, *, state: str = "ready", part: str = "sheet") -> int:
    """An open assignment of course l03 whose pool (seed 391, k=3) is `state`: ready, v391-1 dropped by its check and
    the two others kept; or measuring, every variant still measuring."""
    from grader.core.db import new_session
    from grader.core.models import PoolVariant, User, VariantPool, utcnow

    response = create(api, part=part, title="Own lab", open_at=at(hours=-1), due_at=at(days=2),
                      hard_close_at=at(days=3))
    assert response.status_code == 201, response.text
    assignment_id = response.json()["id"]
    space = rubric.load_variant_space("L03")
    with new_session() as session:
        prof = session.scalar(select(User).where(User.name == "prof"))
        pool = VariantPool(assignment_id=assignment_id, lesson="L03", space_version=space.version,
                           space_hash=space.content_hash, rubric_version="2", seed=SEED, k=K, state=state, rejected=[],
                           created_by_id=prof.id, ready_at=utcnow() if state == "ready" else None)
        session.add(pool)
        session.flush()
        for position, variant in enumerate(drawn().values(), 1):
            decided = "dropped" if variant.id == DROPPED else "kept"
            session.add(PoolVariant(pool_id=pool.id, name=variant.id, position=position,
                                    parameters=variant.parameters, digest=variant.digest,
                                    state=decided if state == "ready" else "measuring",
                                    reason="lab check failed: substeps_reduce_proxy" if decided == "dropped" else None))
        session.commit()
    return assignment_id


def variant_of(assignment_id: int, who: str) -> str | None:
    """The variant fixed for `who` at the assignment, by id (v391-2), or None while none is."""
    from grader.core.db import new_session
    from grader.core.models import StudentVariant, User

    with new_session() as session:
        student = session.scalar(select(User).where(User.name == who))
        row = session.scalar(select(StudentVariant).where(StudentVariant.assignment_id == assignment_id,
                                                          StudentVariant.student_id == student.id))
        return row.variant.name if row is not None else None


def words(text: str) -> str:
    """`text` as a page escapes it."""
    return str(escape(text))


def test_each_student_reads_only_their_own_labs_parameters_on_the_course_page_and_the_form(api):
    assignment_id = pooled_assignment(api)
    variants = drawn()
    book = rubric.load_rubric("L03")
    seen = {}
    for who in ("alice", "bob"):
        course = api.client.get("/courses/l03", headers=api.as_(who))
        assert course.status_code == 200, course.text
        seen[who] = variant_of(assignment_id, who)  # fixed at this first view
        assert seen[who] in KEPT
    # the kept variant with the fewest students: the two students have the two kept variants
    assert sorted(seen.values()) == sorted(KEPT)
    for who, locale, headers in (("alice", "en", {}), ("bob", "zh", ZH)):
        own, other = variants[seen[who]], variants[next(v for v in KEPT if v != seen[who])]
        course = api.client.get("/courses/l03", headers=api.as_(who) | headers).text
        form = api.client.get(f"/assignments/{assignment_id}/sheet", headers=api.as_(who) | headers).text
        assert variant_of(assignment_id, who) == own.id  # every later view meets the same variant
        for page in (course, form):
            assert words(texts.parameter_summary(own, locale)) in page
            for variant in (other, variants[DROPPED]):  # never another variant's parameters
                assert words(texts.parameter_summary(variant, locale)) not in page
                assert words(texts.parameter_summary(variant, "en")) not in page
        # the course page's table marks what differs from the lesson
        rows = texts.parameter_rows(own, locale)
        assert f'id="assignment-{assignment_id}-lab-table"' in course
        differs = [name for name, _, _, changed in rows if changed]
        assert differs and "table_friction" in differs
        # the form: B1 names the student's table frictions, in the reader's language
        b1 = texts.item_question(book.item("B1"), own, locale)
        assert words(b1) in form and own.parameters["table_friction"] != 0.5
        assert words(texts.item_question(book.item("B1"), None, locale)) not in form
        assert words(texts.item_question(book.item("B1"), other, locale)) not in form
    # the API's list of the pool stays staff-only
    for who in ("alice", "bob"):
        assert api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_(who)).status_code == 403


def test_a_students_form_starts_from_their_variants_baseline_and_checks_one_factor_against_it(api):
    from grader.core.db import new_session
    from grader.core.models import Submission

    assignment_id = pooled_assignment(api)
    path = f"/assignments/{assignment_id}/sheet"
    pages = {who: api.client.get(path, headers=api.as_(who)).text for who in ("alice", "bob")}
    # the student on v391-3, whose duration (1.2 s) changes every sample count
    who = next(w for w in pages if variant_of(assignment_id, w) == "v391-3")
    page, own = pages[who], drawn()["v391-3"]
    p = own.parameters
    cases = own.cases()
    # the config editor: the variant's friction baseline and N1 (the extension's baseline)
    assert f'name="configs.table_exercise.table.friction" value="{p["table_friction"]!r}"' in page
    assert f'name="configs.table_exercise.cube_size" value="{p["cube_size"]!r}"' in page
    assert f'name="configs.table_exercise.lanes.1.friction" value="{p["high_lane_friction"]!r}"' in page
    assert f'name="configs.extension.duration" value="{p["duration"]!r}"' in page
    assert f'name="configs.extension.cube.pos.2" value="{p["cube_start_z"]!r}"' in page
    assert "starts from your lab's case friction-baseline" in page
    # A1's labels name the variant's sample counts
    assert f"<legend>samples {cases['N1'].sample_count} " in page and "<legend>samples 150 " not in page
    assert f"<legend>samples {cases['N3'].sample_count} " in page and "<legend>samples 75 " not in page

    # The hands-on exercise made from the variant's baseline: only the table friction goes to the exercise's.
    exercise = repr(p["exercise_table_friction"])
    fields = form_fields(page, **{"configs.table_exercise.table.friction": exercise, "student": who,
                                  "action": "check"})
    checked = api.client.post(path, data=fields, headers=api.as_(who))
    assert checked.status_code == 200, checked.text
    verdict = f"table_exercise vs friction-baseline: one factor (table.friction {p['table_friction']} -&gt; {exercise})"
    assert verdict in checked.text, checked.text[checked.text.find('id="check-summary"'):][:3000]
    assert "one-factor violation" not in checked.text
    # the saved draft is the config the grader will compare with the same baseline, under the same variant
    with new_session() as session:
        from grader.services.submissions import drafts
        from grader.core.models import Assignment, User

        student = session.scalar(select(User).where(User.name == who))
        draft = drafts.load(session=session, user=student, assignment=session.get(Assignment, assignment_id)).sheet
    config = rubric.sheet.Configs.model_validate(draft["configs"]).table_exercise
    assert config.cube_size == p["cube_size"] and config.table.friction == p["exercise_table_friction"]
    assert [f.ok for f in rubric.one_factor_findings(
        rubric.sheet.PredictionSheet.model_construct(configs=rubric.sheet.Configs.model_validate(draft["configs"])),
        rubric.load_rubric("L03"), own).values()] == [True, True]

    # The lesson's own friction baseline, typed into a variant student's form, breaks the rule against theirs.
    shipped = form_fields(page, **{"configs.table_exercise.cube_size": "0.08", "student": who, "action": "check"})
    broken = api.client.post(path, data=shipped, headers=api.as_(who))
    assert "one-factor violation" in broken.text and f"cube_size: {p['cube_size']} -&gt; 0.08" in broken.text

    # Submitted from the form: the reference answers (imported without configs), the configs as the editor showed
    # them with the exercise's friction. The config is the student's one factor, and runs.
    from tests.grader.pages.test_submit_confirm import confirm_fields

    answers = {k: v for k, v in reference_sheet().items() if k != "configs"} | {"student": who}
    imported = import_yaml(api, yaml.safe_dump(answers), path=path, who=who)
    assert imported.status_code == 200, imported.text
    fields = form_fields(imported.text, **{"configs.table_exercise.table.friction": exercise, "action": "submit"})
    confirm = api.client.post(path, data=fields, headers=api.as_(who))
    assert confirm.status_code == 200 and 'id="confirm-voids"' not in confirm.text, confirm.text
    done = api.client.post(path, data=confirm_fields(confirm.text), headers=api.as_(who), follow_redirects=False)
    assert done.status_code == 303, done.text
    with new_session() as session:
        submission = session.get(Submission, int(done.headers["location"].split("/")[2]))
        runs = {run.name: run.spec for run in submission.case_runs}
        assert submission.variant.name == own.id
    assert runs[SHEET_CASE_PREFIX + "table_exercise"]["table"]["friction"] == p["exercise_table_friction"]
    assert runs[SHEET_CASE_PREFIX + "table_exercise"]["cube_size"] == p["cube_size"]


def test_staff_and_a_free_sheet_keep_the_lessons_parameters(api):
    assignment_id = pooled_assignment(api)
    shipped = texts.parameter_summary(None, "en")
    staff = api.client.get(f"/assignments/{assignment_id}/sheet", headers=api.as_("prof"))
    assert staff.status_code == 200, staff.text
    free = api.client.get("/sheet", headers=api.as_("alice"))
    for page in (staff.text, free.text):
        assert 'id="your-lab"' not in page
        assert 'name="configs.table_exercise.table.friction" value="0.5"' in page
        assert words(rubric.load_rubric("L03").item("B1").question) in page
        assert words(shipped) not in page
    assert variant_of(assignment_id, "prof") is None and variant_of(assignment_id, "alice") is None


def test_while_the_pool_is_measured_the_pages_say_the_lab_is_being_prepared(api):
    assignment_id = pooled_assignment(api, state="measuring")
    course = api.client.get("/courses/l03", headers=api.as_("alice"))
    assert course.status_code == 200, course.text
    assert f'id="assignment-{assignment_id}-lab-preparing"' in course.text
    assert f'href="/assignments/{assignment_id}/sheet"' not in course.text
    form = api.client.get(f"/assignments/{assignment_id}/sheet", headers=api.as_("alice"))
    assert form.status_code == 200 and 'id="lab-preparing"' in form.text and 'id="sheet-form"' not in form.text
    zh = api.client.get(f"/assignments/{assignment_id}/sheet", headers=api.as_("alice") | ZH)
    assert "正在准备" in zh.text, zh.text
    saved = api.client.post(f"/assignments/{assignment_id}/sheet", data={"action": "save", "student": "alice"},
                            headers=api.as_("alice"))
    assert saved.status_code == 409 and 'id="lab-preparing"' in saved.text
    for variant in drawn().values():
        for page in (course.text, form.text):
            assert words(texts.parameter_summary(variant, "en")) not in page
    assert variant_of(assignment_id, "alice") is None


def test_a_variant_submissions_report_asks_the_students_own_questions_in_their_language(api):
    from grader.core.db import new_session
    from grader.core.grading import store_grade
    from grader.core.models import Submission

    assignment_id = pooled_assignment(api)
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet(), "assignment_id": assignment_id},
                               headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    sid = response.json()["id"]
    book = rubric.load_rubric("L03")
    with new_session() as session:  # graded as the grader would, before any run finished (every item not measured)
        submission = session.get(Submission, sid)
        own = drawn()[submission.variant.name]
        report = rubric.grade_sheet(rubric.parse_sheet(submission.sheet), {}, book, own)
        store_grade(session=session, submission=submission, book=book, report=report, execution_s=0.0, complete=True)
        session.commit()
    for locale, headers in (("en", {}), ("zh", ZH)):
        page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice") | headers)
        assert page.status_code == 200, page.text
        assert words(texts.item_question(book.item("B1"), own, locale)) in page.text, locale
        assert words(texts.item_question(book.item("B1"), None, locale)) not in page.text
