"""What both doors (grader.api under /v1, grader.pages) share and neither owns: the database session dependency
(deps), admission (admission), bounded bodies (bodies), security headers (headers), validators and 304s (etag), the
one mapping of domain errors to answers (errors), the access log's redaction (logs). It imports neither door
(import-linter contract web-shared in pyproject.toml)."""
