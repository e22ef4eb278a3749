"""The variants section of the instructor's assignment page (issue 34), on the in-process app (SQLite, enqueueing
recorded): the form generates and measures a pool, typed values and the service's refusals are shown in the page's
words, the pool's variants with their parameters, states and drop reasons, the top-up button while fewer than K are
kept; instructors of the course only."""

from __future__ import annotations

import pytest
from sqlalchemy import select

import rubric
from tests.grader.pages.test_setup_pages import page_post
from tests.grader.services.setup.test_assignments import at, create
from tests.grader.services.setup.test_variants import pool_assignment


def page(api, aid: int, who: str = "prof", lang: str | None = None):
    headers = {**api.as_(who), **({"Cookie": f"grader_lang={lang}"} if lang else {})}
    return api.client.get(f"/assignments/{aid}", headers=headers)


def variant_row(text: str, variant_id: str) -> str:
    """The pool table's row of one variant (its details hold a table of their own)."""
    return text.split(f'<tr id="variant-{variant_id}">')[1].split("\n  </tr>\n")[0]


def decide_all(aid: int, dropped: dict[int, tuple[str, dict | None]]) -> None:
    """Keep every variant of the assignment's pool but those at `dropped` positions (reason, stored check): the pool
    is ready."""
    from grader.core.db import new_session
    from grader.core.models import PoolVariant, VariantPool
    from grader.core.variants import decide

    with new_session() as session:
        rows = session.scalars(select(PoolVariant).join(VariantPool).where(VariantPool.assignment_id == aid)
                               .order_by(PoolVariant.position)).all()
        for row in rows:
            reason, check = dropped.get(row.position, (None, None))
            decide(session, row, kept=reason is None, reason=reason, check=check)
        session.commit()


def test_an_instructor_generates_a_pool_from_the_page_and_reads_each_variant(api):
    aid = pool_assignment(api)
    before = page(api, aid)
    assert before.status_code == 200 and 'id="variants-form"' in before.text
    assert 'name="k" min="1" max="64" value="16"' in before.text  # K_DEFAULT

    posted = page_post(api, f"/assignments/{aid}/variants", {"seed": "7", "k": "3"})
    assert posted.status_code == 303 and posted.headers["location"] == f"/assignments/{aid}#variants"
    assert len(api.sent) == 3 * 9  # each variant's lesson runs and its two configs, sent to the workers
    text = page(api, aid).text
    assert 'id="variants-form"' not in text and "0 of 3 variants checked so far" in text
    drawn = rubric.draw_pool(rubric.load_variant_space("L03"), seed=7, k=3).variants
    for variant in drawn:
        row = variant_row(text, variant.id)
        assert "measuring" in row
        # the parameters that differ from the lesson, each with its unit
        shipped = rubric.variants.shipped_parameters()
        changed = [name for name in variant.parameters if variant.parameters[name] != shipped[name]]
        assert changed and all(f"<code>{name}</code>" in row for name in changed)
        if "cube_start_z" in changed:
            assert f"<code>cube_start_z</code> {variant.parameters['cube_start_z']:g} m" in row
    assert 'id="top-up"' not in text

    check = {"passed": False, "conditions": [
        {"id": "substeps_reduce_proxy", "title": "more substeps reduce the penetration proxy at each outer dt",
         "passed": False, "evidence": "N1 0.035 mm -> N2 6.183 mm\nsecond line"},
        {"id": "other", "title": "passes", "passed": True, "evidence": ""}]}
    decide_all(aid, {1: ("lab check failed: substeps_reduce_proxy (...): N1 0.035 mm -> N2 6.183 mm", check),
                     3: ("parameters refused before measuring: constraint lanes_straddle_table: 0.7 < 0.5 is false",
                         None)})
    text = page(api, aid).text
    assert "1 of 3 variants kept, 2 dropped." in text
    first = variant_row(text, drawn[0].id)
    assert "the lesson's own check failed on its measured runs" in first
    assert "N1 0.035 mm -&gt; N2 6.183 mm" in first and "substeps_reduce_proxy" in first and "second line" not in first
    third = variant_row(text, drawn[2].id)
    assert "break a rule of the variant space" in third and "lanes_straddle_table" in third
    assert 'id="top-up"' in text and "Draws the next 2 variants of seed 7" in text
    zh = page(api, aid, lang="zh").text
    assert 'lang="zh"' in zh and "Draws the next" not in zh and "已保留" in zh

    topped = page_post(api, f"/assignments/{aid}/variants/top-up", {})
    assert topped.status_code == 303
    text = page(api, aid).text
    assert "of 5 variants checked so far" in text and 'id="top-up"' not in text


def test_typed_values_and_the_services_refusals_are_shown_in_the_pages_words(api):
    aid = pool_assignment(api)
    bad = page_post(api, f"/assignments/{aid}/variants", {"seed": "seven", "k": "65"})
    assert bad.status_code == 422 and 'id="variants-errors"' in bad.text
    assert "Seed: a whole number from 0 to 2147483647" in bad.text
    assert "Variants to keep (K): a whole number from 1 to 64" in bad.text
    assert 'value="seven"' in bad.text and api.sent == []

    opened = create(api, part="sheet", title="Open already", open_at=at(hours=-1)).json()["id"]
    assert "This assignment opened at" in page(api, opened).text
    refused = page_post(api, f"/assignments/{opened}/variants", {"seed": "7", "k": "2"})
    assert refused.status_code == 409 and 'id="variants-refused"' in refused.text
    assert "“Open already” opened at" in refused.text and "a pool is generated before an assignment opens" in refused.text
    zh = page_post(api, f"/assignments/{opened}/variants", {"seed": "7", "k": "2"}, Cookie="grader_lang=zh")
    assert zh.status_code == 409 and "a pool is generated before" not in zh.text and "“Open already”" in zh.text

    assert page_post(api, f"/assignments/{aid}/variants", {"seed": "7", "k": "2"}).status_code == 303
    again = page_post(api, f"/assignments/{aid}/variants", {"seed": "8", "k": "2"})
    assert again.status_code == 409 and "has a pool already (seed 7, 2 variants)" in again.text
    early = page_post(api, f"/assignments/{aid}/top-up".replace("top-up", "variants/top-up"), {})
    assert early.status_code == 409 and "still being measured" in early.text


@pytest.mark.parametrize("who", ["alice", "tess", "eve"])
def test_only_the_courses_instructors_read_or_generate_a_pool(api, who):
    aid = pool_assignment(api)
    assert page_post(api, f"/assignments/{aid}/variants", {"seed": "7", "k": "2"}).status_code == 303
    sent = len(api.sent)
    for path in (f"/assignments/{aid}/variants", f"/assignments/{aid}/variants/top-up"):
        response = page_post(api, path, {"seed": "8", "k": "2"}, who=who)
        assert response.status_code == 404 and "v7-1" not in response.text, (who, path)
    assert page(api, aid, who=who).status_code == 404
    assert len(api.sent) == sent


def test_the_form_asks_for_k_kept_a_budget_a_minimum_and_a_space_and_the_pool_says_what_students_see(api):
    """Issue 47: K is kept, within a stated draw budget; students wait for the minimum, and the page says what they
    see meanwhile; variants can be added to the pool at any time."""
    from grader.core.db import new_session
    from grader.core.models import VariantPool

    aid = pool_assignment(api)
    text = page(api, aid).text
    assert 'name="budget"' in text and 'name="minimum"' in text
    assert '<option value="1">v1</option><option value="2" selected>v2</option>' in text  # the latest by default
    bad = page_post(api, f"/assignments/{aid}/variants", {"seed": "7", "k": "2", "budget": "1", "minimum": "3"})
    assert bad.status_code == 422 and api.sent == []
    assert "Draw budget: a whole number from 2 to 8" in bad.text
    assert "Kept before students get one: a whole number from 1 to 2" in bad.text

    posted = page_post(api, f"/assignments/{aid}/variants",
                       {"seed": "7", "k": "2", "budget": "3", "minimum": "1", "space_version": "1"})
    assert posted.status_code == 303, posted.text
    with new_session() as session:
        pool = session.scalar(select(VariantPool).where(VariantPool.assignment_id == aid))
        assert (pool.space_version, pool.k, pool.draw_budget, pool.minimum) == ("1", 2, 3, 1)
    text = page(api, aid).text
    assert "Drawing until 2 are kept: 2 of at most 3 variants drawn so far." in text
    assert "Until 1 are kept, students are told on the course page that their lab is being prepared" in text
    decide_all(aid, {})
    text = page(api, aid).text
    assert "Kept 2 of the 2 asked for, in 2 variants drawn." in text
    assert "Students get a variant at their first visit." in text

    refused = page_post(api, f"/assignments/{aid}/variants/top-up", {"more": "0"})
    assert refused.status_code == 422 and "Variants more to keep: a whole number from 1 to 64" in refused.text
    added = page_post(api, f"/assignments/{aid}/variants/top-up", {"more": "2"})
    assert added.status_code == 303, added.text
    text = page(api, aid).text
    assert "Drawing until 4 are kept: 4 of at most 7 variants drawn so far." in text
    assert "Students get a variant at their first visit." in text  # the two kept serve while the new are measured
