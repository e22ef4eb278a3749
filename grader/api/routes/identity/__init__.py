"""The API's identity routes (grader.services.identity): revoking a student's tokens."""
