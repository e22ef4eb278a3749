"""grader.services.submissions.submit."""
