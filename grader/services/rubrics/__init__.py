"""grader.services.rubrics."""
