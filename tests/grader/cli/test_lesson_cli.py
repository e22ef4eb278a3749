"""`grader lesson check` refuses a broken lesson before a course can use it, naming the file, the field and the rule
(issue 45, item 6); `grader lesson list` shows what is installed. L03's own check, lab check included, runs in
tests/grader/cli/test_check_cli.py."""

from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from grader.cli import main
from rubric.rubrics import LESSONS_DIR


def grader(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.fixture
def authored(tmp_path) -> Path:
    """A lesson author's copy of L03, not installed: its reviewed files in files/, declared by lesson.py."""
    folder = tmp_path / "my-lesson"
    shutil.copytree(LESSONS_DIR, folder / "files", ignore=shutil.ignore_patterns("*.json"))
    (folder / "lesson.py").write_text(textwrap.dedent("""
        import dataclasses
        from pathlib import Path

        from rubric.l03 import LESSON as L03

        LESSON = dataclasses.replace(L03, files=Path(__file__).parent / "files")
    """))
    return folder


def edit(path: Path, change) -> None:
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    change(data)
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False), encoding="utf-8")


def test_list_names_l03_by_its_entry_point():
    listed = grader("lesson", "list")
    assert listed.exit_code == 0
    assert "L03  L03 · Rigid-body contact, timesteps and friction  (rubric versions 1, 2; languages en, zh; " \
           "entry point L03 = rubric.l03:LESSON)" in listed.output


def test_an_unchanged_copy_of_l03_has_no_problem(authored):
    done = grader("lesson", "check", str(authored), "--no-run")
    assert done.exit_code == 0, done.output
    assert f"lesson L03: L03 · Rigid-body contact, timesteps and friction ({authored / 'lesson.py'})" in done.output
    assert "L03: no problem (its lab check was not run: --no-run)" in done.output


def test_a_missing_chinese_question_is_refused_naming_the_item(authored, tmp_path):
    from rubric import load_rubric

    question = load_rubric("L03").item("C5").question
    edit(authored / "files" / "L03.zh.yaml", lambda data: data["questions"].pop(question))
    done = grader("lesson", "check", str(authored), "--out", str(tmp_path / "out"))
    assert done.exit_code == 1
    assert (f"PROBLEM L03.zh.yaml: questions.{question!r}: item C5 of L03-v1.yaml has no zh text"
            in done.output), done.output
    assert "L03: 1 problem; nothing was run" in done.output and not (tmp_path / "out").exists()


def test_an_unreviewed_tolerance_is_refused_naming_the_field(authored):
    def unreview(data):
        del data["tolerances"]["stop_distance_resolution"]["reviewer"]
    edit(authored / "files" / "L03-v2.yaml", unreview)
    done = grader("lesson", "check", str(authored), "--no-run")
    assert done.exit_code == 1
    assert "PROBLEM L03-v2.yaml: tolerances.stop_distance_resolution.reviewer: Field required" in done.output


def test_an_item_without_a_scoring_rule_is_refused(authored):
    def rename(data):
        data["items"][3]["check"] = "array_lengths_by_eye"
    edit(authored / "files" / "L03-v2.yaml", rename)
    done = grader("lesson", "check", str(authored), "--no-run")
    assert done.exit_code == 1
    item = yaml.safe_load((authored / "files" / "L03-v2.yaml").read_text())["items"][3]["id"]
    assert (f"PROBLEM L03-v2.yaml: items.3.check: item {item} names scoring rule 'array_lengths_by_eye', which L03 "
            "does not have") in done.output


def test_an_unknown_lesson_and_a_file_declaring_none_are_refused(tmp_path):
    unknown = grader("lesson", "check", "L99")
    assert unknown.exit_code == 1 and "no lesson 'L99' is installed (entry points l03_grader.lessons: L02, L03)" in unknown.output
    empty = tmp_path / "lesson.py"
    empty.write_text("LESSON = 'L02'\n")
    refused = grader("lesson", "check", str(empty))
    assert refused.exit_code == 1 and "LESSON is str, not a rubric.lesson.Lesson" in refused.output
