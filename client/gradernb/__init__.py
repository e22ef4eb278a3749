"""Answer, check and submit a prediction sheet from the Jupyter notebook a student works in, and read the report
there: a client of the grading service's HTTP API (no Genesis, torch, database or queue in the kernel).

    grader = gradernb.connect("https://grader.example.edu", token="...")
    grader.assignments()                   # the course's assignments, as a table
    sheet = grader.sheet(3)                # your own lab, your saved draft, what a submission now would be
    sheet.set("A2", direction="decrease")  # or sheet.collect(globals()): every `A2 = {...}` answer cell
    sheet.check()                          # the sheet page's Check: errors and one-factor verdicts
    submission = sheet.submit()            # attempt, lateness, penalty; a progress bar while the cases run
    submission.report()                    # total, lab check, each item's verdict and evidence, charts, a link
"""

from gradernb.api import Grader, GraderError, connect
from gradernb.sheet import Check, Sheet, Submission

__all__ = ["connect", "Grader", "GraderError", "Sheet", "Check", "Submission"]
