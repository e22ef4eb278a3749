"""Grade exports: a class CSV (one row per student, one column per item) and Gradescope's results.json."""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Iterable, Mapping, Sequence

from .scoring import GradeReport

CSV_FIXED_COLUMNS = ("student", "rubric_version", "total", "max_total", "complete")
# A spreadsheet evaluates a cell starting with one of these as a formula (OWASP's CSV injection list).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def spreadsheet_safe(cell: object) -> object:
    """The cell, with a leading ' where a spreadsheet would evaluate it (a student id `=HYPERLINK(...)`, `@SUM(...)`,
    `-2+3`); a plain number such as a penalty `-5` stays a number."""
    text = str(cell)
    if text.startswith(FORMULA_STARTS) and not _NUMBER.fullmatch(text):
        return "'" + text
    return cell


def csv_text(rows: Iterable[Sequence[object]]) -> str:
    """CSV text of the rows, every cell through spreadsheet_safe: the one writer of every CSV export."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerows([spreadsheet_safe(cell) for cell in row] for row in rows)
    return out.getvalue()


def _number(value: float) -> str:
    """Scores without float noise: 2.0 -> '2', 0.5 -> '0.5'."""
    return f"{value:g}"


def grades_csv(reports: Sequence[tuple[str, GradeReport]], *,
               submissions: Sequence[tuple[int, str]] | None = None) -> str:
    """CSV text: fixed columns, then one score column per rubric item in rubric order.

    `submissions` (one (id, submitted_at ISO time) per report) adds the columns submission_id and submitted_at
    after the student, so a row can be traced to the attempt it grades.
    An inconclusive item is written as an empty cell: it is not counted, and a 0 would read as a penalty.
    Reports may come from different rubric versions; the item columns are their union, first seen first.
    Where any report was graded on a per-student variant, a `variant` column follows rubric_version (empty for a
    report on the lesson's own parameters); without variants the columns are as they always were.
    """
    if submissions is not None and len(submissions) != len(reports):
        raise ValueError(f"{len(submissions)} submissions for {len(reports)} reports")
    # Reports of more than one lesson (a course teaching two): a `lesson` column first, and each item's column named
    # with its lesson (`L02.C1`, `L03.C1`), since two lessons' items may share an id; one lesson's file is as it was.
    mixed = len({report.lesson for _, report in reports}) > 1

    def column(report: GradeReport, item_id: str) -> str:
        return f"{report.lesson}.{item_id}" if mixed else item_id

    item_ids: list[str] = []
    for _, report in reports:
        item_ids += [c for i in report.items if (c := column(report, i.id)) not in item_ids]
    traced = ["submission_id", "submitted_at"] if submissions is not None else []
    varied = any(report.variant is not None for _, report in reports)
    fixed = [CSV_FIXED_COLUMNS[1], "variant", *CSV_FIXED_COLUMNS[2:]] if varied else list(CSV_FIXED_COLUMNS[1:])
    rows = [[CSV_FIXED_COLUMNS[0], *traced, *(["lesson"] if mixed else []), *fixed, *item_ids]]
    for n, (student, report) in enumerate(reports):
        scores = {column(report, i.id): ("" if i.verdict == "inconclusive" else _number(i.score)) for i in report.items}
        trace = [str(submissions[n][0]), submissions[n][1]] if submissions is not None else []
        variant = [report.variant or ""] if varied else []
        rows.append([student, *trace, *([report.lesson] if mixed else []), report.rubric_version, *variant,
                     _number(report.total), _number(report.max_total), str(report.complete).lower(),
                     *(scores.get(i, "") for i in item_ids)])
    return csv_text(rows)


GRADESCOPE_VISIBILITIES = ("visible", "after_due_date", "after_published", "hidden")


def gradescope_results(report: GradeReport, execution_time: float,
                       visibility: Mapping[str, str] | None = None) -> dict:
    """Gradescope autograder results.json: overall score and one test per rubric item, each with Gradescope's
    visibility: `visibility` maps an item id to one of GRADESCOPE_VISIBILITIES ("visible" where it says none)."""
    if execution_time < 0:
        raise ValueError(f"execution_time must be >= 0 seconds, got {execution_time}")
    visibility = visibility or {}
    unknown = {k: v for k, v in visibility.items() if v not in GRADESCOPE_VISIBILITIES}
    if unknown:
        raise ValueError(f"Gradescope visibility must be one of {', '.join(GRADESCOPE_VISIBILITIES)}; got {unknown}")
    on = f" on variant {report.variant}" if report.variant is not None else ""
    # The results' own output and score tell every item: while a test is withheld they take the most withholding of
    # the tests' visibilities, and the output leaves out the total, and the one-factor findings while a config item
    # is withheld (they are its answer), so that what is visible tells no withheld test.
    # Gradescope's two gates are independent (an assignment can be published before its due date): tests behind
    # both make the results hidden
    gated = {visibility.get(i.id, "visible") for i in report.items} - {"visible"}
    strictest = "visible" if not gated else gated.pop() if len(gated) == 1 else "hidden"
    header = (f"{report.lesson} graded under rubric version {report.rubric_version} "
              f"(sha256 {report.rubric_hash[:12]}){on}"
              + (f": {_number(report.total)} / {_number(report.max_total)}" if strictest == "visible" else ""))
    config_held = any(i.kind == "config" and visibility.get(i.id, "visible") != "visible" for i in report.items)
    notes = [] if config_held else [f"config: {finding}" for finding in report.config_findings]
    if not report.complete and strictest == "visible":
        notes.append("some items could not be measured; they score 0 until the cases are measured")
    return {
        "score": report.total,
        "execution_time": round(float(execution_time), 3),
        "output": "\n".join([header, *notes]),
        **({} if strictest == "visible" else {"visibility": strictest}),
        "tests": [
            {
                "name": f"{item.id}: {item.question}",
                "score": item.score,
                "max_score": item.max_score,
                "output": item.feedback,
                "visibility": visibility.get(item.id, "visible"),
            }
            for item in report.items
        ],
    }
