"""The lock files the images install (requirements/*.lock) agree with pyproject.toml, the one list of dependencies:
every requirement is pinned there within its range, nothing is pinned as ours that pyproject.toml dropped, every pin
carries hashes, and the API's lock holds no engine (issue 36)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

from tests.factories import ROOT

ENGINE = {"genesis-world", "torch", "quadrants"}
# Each lock and the pyproject.toml sections it pins (the test extra is not locked: no image installs it).
LOCKS = {"api.lock": (), "worker.lock": ("worker",)}


def requirements(pyproject: dict, extras: tuple[str, ...]) -> list[Requirement]:
    project = pyproject["project"]
    found = [Requirement(r) for r in project["dependencies"]]
    for extra in extras:
        found += [Requirement(r) for r in project["optional-dependencies"][extra]]
    return found


def parse_lock(text: str) -> dict[str, dict]:
    """name -> {version, hashes, via} from pip-compile's output: `name==version \\`, its `--hash=` and `# via` lines."""
    pins: dict[str, dict] = {}
    current: dict | None = None
    via_block = False
    for line in text.splitlines():
        if match := re.match(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==(\S+)", line):
            current = pins[canonicalize_name(match[1])] = {"version": Version(match[2]), "hashes": [], "via": []}
            via_block = False
        elif current is not None and (match := re.match(r"^\s+--hash=sha256:([0-9a-f]{64})", line)):
            current["hashes"].append(match[1])
        elif current is not None and (match := re.match(r"^\s+#\s+via\s*(.*)$", line)):
            via_block = True
            if match[1]:
                current["via"].append(match[1].strip())
        elif current is not None and via_block and (match := re.match(r"^\s+#\s+(\S.*)$", line)):
            current["via"].append(match[1].strip())
        elif line.strip() and not line.startswith(" ") and not line.startswith("#"):
            raise AssertionError(f"a line pip-compile does not write: {line!r}")
    return pins


def disagreements(pyproject: dict, lock_text: str, extras: tuple[str, ...],
                  owner: str = "l03-grader (pyproject.toml)") -> list[str]:
    """What makes a lock disagree with pyproject.toml, in words; empty when they agree. `owner`: how pip-compile
    names the project in its `# via` lines."""
    wanted = requirements(pyproject, extras)
    pins = parse_lock(lock_text)
    problems = []
    for req in wanted:
        pin = pins.get(canonicalize_name(req.name))
        if pin is None:
            problems.append(f"{req} is not pinned")
        elif not req.specifier.contains(pin["version"], prereleases=True):
            problems.append(f"{req} but the lock pins {pin['version']}")
    ours = {name for name, pin in pins.items() if owner in pin["via"]}
    for name in sorted(ours - {canonicalize_name(r.name) for r in wanted}):
        problems.append(f"{name} is pinned as pyproject.toml's own requirement, which it no longer is")
    problems += [f"{name} has no hash" for name, pin in pins.items() if not pin["hashes"]]
    return problems


@pytest.fixture(scope="module")
def pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


@pytest.mark.parametrize("lock", sorted(LOCKS))
def test_each_lock_agrees_with_pyproject(pyproject, lock):
    text = (ROOT / "requirements" / lock).read_text()
    assert disagreements(pyproject, text, LOCKS[lock]) == [], (
        f"requirements/{lock} disagrees with pyproject.toml: regenerate it as requirements/README.md says")


def test_the_api_lock_holds_no_engine_and_the_worker_lock_does(pyproject):
    api = parse_lock((ROOT / "requirements" / "api.lock").read_text())
    worker = parse_lock((ROOT / "requirements" / "worker.lock").read_text())
    assert not ENGINE & set(api), "the API image must not install Genesis or torch"
    assert {"genesis-world", "torch"} <= set(worker)
    assert not {canonicalize_name(r.name) for r in requirements(pyproject, ())} & ENGINE


# The notebook client (client/, issue 48) is a distribution of its own: its lock pins its pyproject.toml, and what a
# student installs in their kernel holds no engine, database or queue.
CLIENT = ROOT / "client" / "pyproject.toml"
NOT_IN_THE_CLIENT = ENGINE | {"sqlalchemy", "celery", "kombu", "fastapi", "psycopg2-binary", "l03-grader"}


def test_the_client_lock_agrees_with_the_clients_pyproject_and_holds_no_engine():
    client = tomllib.loads(CLIENT.read_text())
    text = (ROOT / "requirements" / "client.lock").read_text()
    assert disagreements(client, text, (), owner="l03-grader-client (client/pyproject.toml)") == [], (
        "requirements/client.lock disagrees with client/pyproject.toml: regenerate it as requirements/README.md says")
    assert not NOT_IN_THE_CLIENT & set(parse_lock(text))
    missing = re.sub(r"(?ms)^httpx==.*?(?=^\S)", "", text)
    assert disagreements(client, missing, (), owner="l03-grader-client (client/pyproject.toml)") == [
        "httpx>=0.27 is not pinned"]


def test_a_lock_that_drifted_from_pyproject_is_caught(pyproject):
    """The check can fail: a requirement dropped from the lock, a pin outside its range, and a lock still pinning a
    requirement pyproject.toml no longer lists are each named."""
    text = (ROOT / "requirements" / "api.lock").read_text()
    missing = re.sub(r"(?ms)^limits==.*?(?=^\S)", "", text)
    assert disagreements(pyproject, missing, ()) == ["limits==5.8.0 is not pinned"]
    out_of_range = text.replace("\nlimits==5.8.0 ", "\nlimits==5.7.0 ")
    assert disagreements(pyproject, out_of_range, ()) == ["limits==5.8.0 but the lock pins 5.7.0"]
    dropped = dict(pyproject, project={**pyproject["project"], "dependencies": [
        r for r in pyproject["project"]["dependencies"] if not r.startswith("limits")]})
    assert disagreements(dropped, text, ()) == [
        "limits is pinned as pyproject.toml's own requirement, which it no longer is"]


def test_no_dockerfile_lists_a_python_package_by_hand():
    """pip in an image installs a lock (`-r requirements/...`) or the project itself (`.`), never a named package."""
    for dockerfile in sorted((ROOT / "docker").glob("*Dockerfile")):
        text = dockerfile.read_text().replace("\\\n", " ")
        for command in re.findall(r"pip install([^&;\n]*)", text):
            command = re.sub(r"\$\{[^}]*\}", "", command)  # a shell expansion: an index URL, never a package
            words = [w for w in command.split() if not w.startswith("-") and not w.startswith("$")]
            # the option values that follow -r / --find-links / --constraint are paths, the rest must be "."
            values = re.findall(r"(?:-r|--requirement|-c|--constraint|--find-links)[ =](\S+)", command)
            assert [w for w in words if w not in values] in ([], ["."]), (dockerfile.name, command)
