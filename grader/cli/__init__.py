"""The `grader` command line; one module per command group, collected here.

Commands are taken as module attributes so `grader.cli.grade` etc. stay the submodules (tests patch them).
"""

import click

from . import assignment, case, check, course, grade, lesson, lti, roster, rubric, service


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def main() -> None:
    """Autograder for the Genesis course: its lessons are installed packages (`grader lesson list`)."""


for command in (assignment.assignment, case.case, check.check, course.course, grade.grade, lesson.lesson, lti.lti,
                roster.roster,
                rubric.rubric,
                *service.COMMANDS):
    main.add_command(command)
