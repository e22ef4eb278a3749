"""Isolated case process: `python -m worker.isolated_process SPEC.json OUT_DIR` runs one case and exits.

The lesson's way, one fresh process per case; used for audits.
"""

import json
import sys
from pathlib import Path

from rubric.lesson import parse_spec


def main(argv: list[str]) -> int:
    spec_path, out_dir = Path(argv[0]), Path(argv[1])
    spec = parse_spec(json.loads(spec_path.read_text()))
    from .engine import run_case_in_genesis  # lazy: worker.engine is imported only when a case process runs a case

    return run_case_in_genesis(spec, out_dir, mode="isolated")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
