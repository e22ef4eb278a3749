"""The notebook client (client/, l03-grader-client) installs alone in a clean virtualenv: the installed set holds no
Genesis, torch, SQLAlchemy, Celery or the service itself, and `gradernb` imports (issue 48)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest
from packaging.utils import canonicalize_name

from tests.factories import ROOT
from tests.test_lock import NOT_IN_THE_CLIENT, parse_lock

pytestmark = pytest.mark.slow


def test_the_client_installs_in_a_clean_virtualenv_without_the_engine_or_the_service(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "--disable-pip-version-check"]
    # the lock first, as a student's course would pin it, then the client itself without resolving anything else
    subprocess.run(pip + ["install", "-q", "--require-hashes", "-r", str(ROOT / "requirements" / "client.lock")],
                   check=True, capture_output=True)
    source = shutil.copytree(ROOT / "client", tmp_path / "client",  # built outside the tree: no build/ left there
                             ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    subprocess.run(pip + ["install", "-q", "--no-deps", str(source)], check=True, capture_output=True)
    listed = json.loads(subprocess.run(pip + ["list", "--format=json"], check=True, capture_output=True,
                                       text=True).stdout)
    installed = {canonicalize_name(p["name"]) for p in listed}
    assert "l03-grader-client" in installed
    assert not installed & NOT_IN_THE_CLIENT, installed & NOT_IN_THE_CLIENT
    assert installed - {"pip", "setuptools", "l03-grader-client"} == set(parse_lock(
        (ROOT / "requirements" / "client.lock").read_text()))
    subprocess.run(pip[:1] + ["-c", "import gradernb, sys; assert 'sqlalchemy' not in sys.modules; "
                                    "print(gradernb.__all__)"], check=True, cwd=tmp_path)
    check = subprocess.run(pip + ["check"], capture_output=True, text=True)
    assert check.returncode == 0, check.stdout
