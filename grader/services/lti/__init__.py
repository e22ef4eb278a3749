"""grader.services.lti.launch."""
