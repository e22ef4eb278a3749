"""The sheet form of another lesson (issue 45): an L02 assignment's page asks L02's items with the inputs its sheet
model says, edits its exercise config from L02's own baseline, checks it by L02's one-factor rule and submits an L02
sheet; in English and Chinese. Nothing of the form names L02: it reads the lesson's declaration."""

from __future__ import annotations

from pathlib import Path

import yaml
from markupsafe import escape

from rubric import load_rubric
from tests.grader.pages.test_sheet_form import form_fields, import_yaml
from tests.grader.pages.test_submit_confirm import confirm_fields
from tests.grader.services.setup.test_assignments import create

L02_YAML = (Path(__file__).resolve().parents[3] / "examples" / "l02" / "reference.yaml").read_text()
ZH = {"Accept-Language": "zh-CN,zh;q=0.9,en;q=0.8"}


def _l02_assignment(api) -> int:
    made = create(api, lesson="L02", part="sheet", title="Lifecycle")
    assert made.status_code == 201, made.text
    assert made.json()["item_ids"] == ["C1", "C2", "C3", "P1", "P2", "P3", "P4", "E1"]
    return made.json()["id"]


def test_an_l02_assignments_form_asks_its_items_and_edits_its_exercise(api):
    aid = _l02_assignment(api)
    page = api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert page.status_code == 200, page.text
    book = load_rubric("L02")
    for item in book.items:
        assert f'id="item-{item.id}"' in page.text and str(escape(item.question)) in page.text, item.id
    assert 'id="item-A1"' not in page.text and 'name="configs.table_exercise' not in page.text
    assert 'type="radio" name="answers.P4.lower" value="same"' in page.text
    assert 'name="answers.C2.internal_dt.value"' in page.text and 'name="answers.E1.internal_updates"' in page.text
    # The exercise starts from S1, its rule's baseline: dt 0.01 s, one substep, the lesson's 0.6 s.
    assert 'id="config-exercise"' in page.text
    assert 'name="configs.exercise.dt" value="0.01"' in page.text
    assert 'name="configs.exercise.duration" value="0.6"' in page.text
    zh = api.client.get(f"/assignments/{aid}/sheet", headers={**api.as_("alice"), **ZH})
    assert '<html lang="zh">' in zh.text and "盒子何时首次接触地面" in zh.text


def test_check_applies_l02s_one_factor_rule_to_its_exercise(api):
    aid = _l02_assignment(api)
    page = import_yaml(api, L02_YAML, path=f"/assignments/{aid}/sheet")
    assert page.status_code == 200, page.text
    fields = form_fields(page.text)
    checked = api.client.post(f"/assignments/{aid}/sheet", headers=api.as_("alice"), data={**fields, "action": "check"})
    assert checked.status_code == 200, checked.text
    assert "exercise vs S1: one factor (dt 0.01 -&gt; 0.004, substeps 1 -&gt; 3)" in checked.text
    broken = {**fields, "configs.exercise.duration": ["0.8"]}
    checked = api.client.post(f"/assignments/{aid}/sheet", headers=api.as_("alice"), data={**broken, "action": "check"})
    assert "too many inputs changed at once" in checked.text and "only dt, substeps may change" in checked.text


def test_an_l02_sheet_submits_from_the_form_as_its_yaml_says(api):
    aid = _l02_assignment(api)
    page = import_yaml(api, L02_YAML, path=f"/assignments/{aid}/sheet")
    shown = api.client.post(f"/assignments/{aid}/sheet", headers=api.as_("alice"),
                            data={**form_fields(page.text), "action": "submit"})
    assert shown.status_code == 200, shown.text
    done = api.client.post(f"/assignments/{aid}/sheet", headers=api.as_("alice"), data=confirm_fields(shown.text),
                           follow_redirects=False)
    assert done.status_code == 303, done.text
    sid = int(done.headers["location"].split("/")[2])
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Submission

    with new_session() as session:
        stored = session.get(Submission, sid)
        assert stored.lesson == "L02" and stored.sheet == yaml.safe_load(L02_YAML)
        runs = sorted(run.name for run in session.query(CaseRun).filter(CaseRun.submission_id == sid))
    assert runs == ["S1", "S2", "sheet.exercise"]
