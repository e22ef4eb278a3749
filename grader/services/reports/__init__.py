"""grader.services.reports."""
