"""`python -m grader.cli` runs the command line (used by tests that need a real process)."""

from . import main

main()
