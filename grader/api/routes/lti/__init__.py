"""The API's LMS routes (grader.services.lti): platform registrations, scores sent, roster sync."""
