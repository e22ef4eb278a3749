"""The layers of ARCHITECTURE.md hold: import-linter's contracts (pyproject.toml) pass on the tree, and fail when a
page imports an API route module or the neutral core imports the worker."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.factories import ROOT

LINT = [sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command; "
        "sys.exit(lint_imports_command())", "--no-cache"]


def _lint(tree: Path, contract: str | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    only = ["--contract", contract] if contract else []
    return subprocess.run([*LINT, "--config", str(tree / "pyproject.toml"), *only], cwd=tree, env=env,
                          capture_output=True, text=True, timeout=300)


def test_every_import_contract_is_kept():
    result = _lint(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout and "11 kept" in result.stdout, result.stdout


@pytest.fixture
def tree_copy(tmp_path):
    for name in ("grader", "worker", "rubric", "lessons"):
        shutil.copytree(ROOT / name, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


@pytest.mark.parametrize("module, line, contract, offender", [
    ("grader/pages/templates.py", "from grader.api.routes.reports import audit as _audit", "pages-use-services",
     "grader.pages.templates -> grader.api.routes.reports.audit"),
    ("grader/core/lifecycle.py", "from worker import case_run as _case_run", "core-neutral",
     "grader.core.lifecycle -> worker.case_run"),
    ("grader/services/submissions/visibility.py", "from fastapi import HTTPException as _http", "services-below-web",
     "grader.services.submissions.visibility -> fastapi"),
    ("rubric/guards.py", "import sqlalchemy as _sql", "rubric-pure", "rubric.guards -> sqlalchemy"),
    ("grader/api/views.py", "from grader.pages import templates as _templates", "web-two-doors",
     "grader.api.views -> grader.pages.templates"),
    ("grader/web/etag.py", "from grader.api import views as _views", "web-shared", "grader.web.etag -> grader.api.views"),
    ("grader/pages/language.py", "from grader import main as _main", "layers", "grader.pages.language -> grader.main"),
    ("grader/core/grading.py", "from grader.web import etag as _etag", "layers", "grader.core.grading -> grader.web.etag"),
    ("worker/engine.py", "from lessons.l03 import scenes as _scenes", "lessons-are-found",
     "worker.engine -> lessons.l03.scenes"),
    ("lessons/l03/scenes.py", "from grader.core import models as _models", "lessons-on-the-framework",
     "lessons.l03.scenes -> grader.core.models"),
])
def test_a_forbidden_import_breaks_its_contract(tree_copy, module, line, contract, offender):
    assert _lint(tree_copy).returncode == 0  # the copy itself keeps every contract
    path = tree_copy / module
    path.write_text(path.read_text() + f"\n{line}  # a forbidden import, added by this test\n")
    result = _lint(tree_copy, contract)
    assert result.returncode != 0 and "BROKEN" in result.stdout and offender in result.stdout, result.stdout
