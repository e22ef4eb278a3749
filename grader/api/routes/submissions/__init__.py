"""The API's submissions routes (grader.services.submissions): submit and read, case runs, evidence files and
series, overrides and review requests."""
