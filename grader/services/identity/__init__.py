"""grader.services.identity."""
