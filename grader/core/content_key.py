"""The content key that lets an identical measurement be reused instead of re-run (the API at admission, the worker
before running a case).

key = sha256 of the canonical JSON of:
  spec            the case spec without computed fields (sorted keys; backend, precision and seed are in it),
  backend         requested backend (cpu | rocm | cuda), again explicitly,
  precision       "32" | "64",
  versions        genesis-world, quadrants and torch as installed where the case runs (the worker),
  runner_version  rubric.results.RUNNER_VERSION, bumped whenever the runner's sampling or arrays change.
Not covered (so they never split or merge keys): the case run, submission or student, the execution mode
(warm and isolated are tested to give identical arrays), host and device name (recorded in provenance).
A key is reused only from a validated (status ok) measurement, and `force_rerun` bypasses reuse.
"""

from __future__ import annotations

import hashlib
import json
from functools import cache
from importlib import metadata
from typing import Any

from rubric import results

ENGINE_PACKAGES = ("genesis-world", "quadrants", "torch")


@cache
def engine_versions() -> dict[str, str]:
    """Installed engine versions, read from package metadata (never by importing the engine)."""
    versions = {}
    for name in ENGINE_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "absent"
    return versions


def key_inputs(spec: dict[str, Any], *, backend: str, precision: str) -> dict[str, Any]:
    return {
        "spec": spec,
        "backend": backend,
        "precision": precision,
        "versions": engine_versions(),
        "runner_version": results.RUNNER_VERSION,  # read at call time: a bump takes effect at once
    }


def content_key(inputs: dict[str, Any]) -> str:
    canonical = json.dumps(inputs, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(canonical.encode()).hexdigest()
