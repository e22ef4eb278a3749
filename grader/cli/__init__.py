"""The `grader` command line; one module per command group, collected here."""

import click

from .bench import bench
from .case import case
from .check import check
from .grade import grade


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def main() -> None:
    """Autograder for the Genesis course (lesson L03)."""


main.add_command(bench)
main.add_command(case)
main.add_command(check)
main.add_command(grade)
