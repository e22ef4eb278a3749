"""The lab check stored with a grade: rubric.check evaluated on a submission's own runs, in a grading service.

The lesson's "How to know the lab worked" is written for a local lab run: child processes the learner started, a
rendering mode the learner chose, an output directory the learner configured. In the service the same conditions are
evaluated on the same kind of evidence, and each condition whose meaning shifts says how in its evidence:
- processes: a case may be a measurement reused from an identical earlier run (grader/core/content_key.py); its provenance is
  the process that produced the numbers, and the evidence names the reuse;
- rendering: the service runs the lesson cases with rendering off, so only the disabled branch (explicit empty
  frames and a rendering SKIP) is exercised; the camera branch is for `grader check --render`;
- outputs: the configured output directory is the service's ARTIFACTS_DIR. Every accepted .npz must have been written
  under it (its bytes are then kept in the database), and it must be outside version control (or ignored by it).
  The service writes no image file (the report's charts are drawn in the reader's browser from the stored arrays),
  so the arrays are the generated files checked. Checked here, never assumed.
Nothing is passed by default: a missing run, an array outside ARTIFACTS_DIR, or an artifacts folder that git would
commit fails its condition like in the lab.
"""

from __future__ import annotations

import subprocess
from collections.abc import Iterable, Mapping
from pathlib import Path

from rubric import CaseResult, Rubric, Variant
from rubric.check import CheckOutcome, OutputLocation
from rubric.lesson import lesson

# Shared by the worker (worker/grading.py, when it completes a grade) and the regrade
# (grader/services/rubrics/regrade.py): a check depends on the rubric version's tolerances, so a regrade evaluates
# it again on the same runs.


def submission_check(results: Mapping[str, CaseResult], *, artifacts_dir: Path, rubric: Rubric,
                     reused: Mapping[str, int] | None = None, variant: Variant | None = None) -> CheckOutcome:
    """The lesson's lab check over the submission's runs of the cases it declares (L03: N1-N4, friction-baseline,
    friction-table-0.30).

    The student's own configs (sheet.*) and the colour-swapped control are not lab-check cases; a check case the
    submission lacks is reported as not run. `reused` maps a case name to the case run whose measurement it reused.
    `variant`: the submission's pool variant (its timing table and duration); None: the lesson's shipped cases.
    """
    declared = lesson(rubric.lesson)
    lab = {name: results[name] for name in declared.check_cases if name in results}
    outputs = output_location(lab.values(), artifacts_dir=Path(artifacts_dir))
    report = declared.evaluate_check(lab, outputs=outputs, rubric=rubric, variant=variant)
    # What a condition means in the service, for the conditions the lesson's check has (its runs' processes, its
    # rendering, its outputs; a lesson without such a condition gets no note for it)
    ids = {c.id for c in report.conditions}
    return report.outcome(notes={k: v for k, v in _service_notes(lab, reused or {}).items() if k in ids})


def _service_notes(lab: Mapping[str, CaseResult], reused: Mapping[str, int]) -> dict[str, str]:
    notes = {}
    names = [n for n in lab if n in reused]
    own = [n for n in lab if n not in reused]
    parts = []
    if own:
        parts.append(f"{', '.join(own)} ran in the grading worker's case processes for this submission")
    if names:
        parts.append(f"{', '.join(f'{n} (case run {reused[n]})' for n in names)} reused identical earlier "
                     "measurements, so their lines report the processes that produced those numbers")
    notes["processes"] = "Service run: " + ("; ".join(parts) or "no check case was run") + "."
    if lab and not any(r.spec.render for r in lab.values()):
        notes["rendering"] = ("Service run: the grading service runs the lesson cases with rendering off, so this "
                              "condition checks only the disabled branch (explicit empty frames and a rendering SKIP); "
                              "the pictures of each case on this page are schematics drawn from measured positions. "
                              "`grader check --render` checks the camera branch (non-empty, finite RGB frames).")
    notes["outputs"] = ("Service run: the configured output directory is the service's ARTIFACTS_DIR (case-run "
                        "folders), not a notebook's output folder.")
    return notes


def output_location(results: Iterable[CaseResult], *, artifacts_dir: Path) -> OutputLocation:
    """Every accepted result's arrays.npz under artifacts_dir, and artifacts_dir outside version control (or ignored
    by it). The service writes no image file (its charts are drawn in the reader's browser from the stored arrays,
    grader/services/reports/series.py), so only the arrays are checked."""
    root = artifacts_dir.resolve()
    accepted = [r for r in results if r.ok and r.out_dir]
    # Where each .npz was written; its bytes are read from the database (stored_result), so a host that lost the
    # folder since loses nothing: a missing array is one the result does not hold.
    arrays = [Path(r.out_dir) / "arrays.npz" for r in accepted]
    outside = [str(p) for p in arrays if not _under(p, root)]
    missing = [str(p) for r, p in zip(accepted, arrays) if not r.arrays]
    lines = [f"{len(arrays)} .npz files under ARTIFACTS_DIR {root} (each kept in the database with its run)"
             if not outside else f"OUTSIDE ARTIFACTS_DIR {root}: {outside[:3]}"]
    if missing:
        lines.append(f"arrays missing: {missing[:3]}")
    passed = bool(arrays) and not outside and not missing
    lines.append("charts: drawn in the reader's browser from the arrays stored in the database, no image file written")
    tracked, detail = _version_control(root)
    lines.append(detail)
    return OutputLocation(passed=passed and not tracked, evidence="; ".join(lines))


def _under(path: Path, root: Path) -> bool:
    return Path(path).resolve().is_relative_to(root)


def _version_control(folder: Path) -> tuple[bool, str]:
    """(could generated files end up in version control, the evidence). A folder inside a git work tree passes only
    if git itself confirms that the folder is ignored and nothing under it is tracked."""
    top = next((p for p in (folder, *folder.parents) if (p / ".git").exists()), None)
    if top is None:
        return False, "not inside a git work tree"
    try:
        ignored = subprocess.run(["git", "-C", str(top), "check-ignore", "-q", str(folder)]).returncode == 0
        tracked = subprocess.run(["git", "-C", str(top), "ls-files", "--", str(folder)],
                                 capture_output=True, text=True).stdout.strip()
    except FileNotFoundError:
        return True, f"inside git work tree {top}, and git is not installed here to confirm that it is ignored"
    if not ignored or tracked:
        return True, (f"inside git work tree {top}: " + ("NOT ignored by git" if not ignored else "ignored")
                      + (f", tracked files present: {tracked.splitlines()[:3]}" if tracked else ""))
    return False, f"inside git work tree {top}, ignored by git and nothing under it tracked"


def lab_check(results: Mapping[str, CaseResult], *, rubric: Rubric, reused: Mapping[str, int],
              artifacts_dir: Path, variant: Variant | None = None) -> tuple[CheckOutcome | None, str]:
    """(the lab check of the submission's runs, or None, and a note for its event). A bug in evaluating the check
    never blocks or changes a grade: the grade then stores no check and the note says why. The note leaves the verdict
    to the report: a student sees the check only once no item of the grade is withheld (grader.services.submissions.visibility)."""
    try:
        check = submission_check(results, artifacts_dir=artifacts_dir, rubric=rubric, reused=reused, variant=variant)
    except Exception as exc:  # noqa: BLE001 - the evidence of a check bug is the event, the grade stands
        return None, f"lab check failed: {type(exc).__name__}: {exc}"
    return check, f"lab check stored ({len(check.conditions)} conditions): its verdict is on the report"
