"""The service layer's door to the rubric's prediction sheets: parse one, list the cases it needs measured, tell a
checkpoint sheet apart. The rubric's sheet API can change in this one place."""

from __future__ import annotations

from typing import Any

import rubric
from rubric.sheet import CHECKPOINT_IDS, answered


def parse_sheet(data: dict[str, Any], part: str = "sheet"):
    """The validated sheet, answering exactly the items named (an assignment's part, or the whole sheet); raises
    pydantic.ValidationError naming each bad item."""

    return rubric.parse_sheet(data, part)


def cases_to_run(sheet) -> list:
    return list(rubric.cases_to_run(sheet))


def checkpoints_only(sheet) -> bool:
    """A sheet answering concept checkpoints alone: it needs only the lesson's own cases, never a config of its own."""

    return set(answered(sheet)) <= set(CHECKPOINT_IDS)
