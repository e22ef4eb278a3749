"""The API's read-model routes (grader.services.reports): the audit log and the exports."""
