"""grader.services.setup."""
