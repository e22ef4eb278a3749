"""The template notebook (examples/l03/sheet.ipynb) filled in as a student would, for the notebook tests."""

from __future__ import annotations

import json

import nbformat

from tests.factories import EXAMPLES

TEMPLATE = EXAMPLES / "sheet.ipynb"


def filled(sheet: dict, *, notebook: dict | None = None) -> dict:
    """The template (or `notebook`) with every answer:ID and config:ROLE cell assigning `sheet`'s value: the
    notebook a student who answered `sheet` saves."""
    nb = json.loads(TEMPLATE.read_text()) if notebook is None else notebook
    for cell in nb["cells"]:
        for tag in cell.get("metadata", {}).get("tags", []):
            kind, _, key = tag.partition(":")
            values = {"answer": sheet["answers"], "config": sheet.get("configs", {})}.get(kind)
            if values is not None and key in values:
                cell["source"] = f"# my answer\n{key} = {values[key]!r}\n"
    return nb


def as_bytes(nb: dict) -> bytes:
    return json.dumps(nb, indent=1).encode()


def validated(nb: dict) -> dict:
    nbformat.validate(nbformat.from_dict(nb))
    return nb
