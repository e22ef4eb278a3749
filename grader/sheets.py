"""The API's door to the rubric's prediction sheets: parse one, list the cases it needs measured.

The rubric is imported inside each function, so the API starts without loading it; its API can change in one place.
"""

from __future__ import annotations

from typing import Any


def parse_sheet(data: dict[str, Any], items: str = "sheet"):
    """The validated sheet, answering exactly the items named (an assignment's part, or the whole sheet); raises
    pydantic.ValidationError naming each bad item."""
    import rubric

    return rubric.parse_sheet(data, items)


def cases_to_run(sheet) -> list:
    import rubric

    return list(rubric.cases_to_run(sheet))
