"""The service layer: domain operations that take a database session and return typed results or raise
grader.services.errors. One package per bounded context; the pages (grader/pages/<context>), the API's routes
(grader/api/routes/<context>) and the templates (grader/templates/<context>) use the same names. Each context's
__init__ lists its modules and their public functions. Nothing here imports FastAPI, Celery, the worker or
grader.web (import-linter contracts in pyproject.toml).

identity     accounts and tokens, page sessions, sign-in links, who may do what (access), per-person limits (quotas)
setup        course settings, the change log, the roster, assignments (dates, attempts, penalties, extensions)
submissions  submit, the sheet models and form, drafts, progress, visibility, overrides, review requests
rubrics      rubric versions of a course: the tolerance review and sign-off, regrade preview and commit
lti          LTI 1.3 registrations, keys, launches, deep links (launch); scores sent to the LMS (outbox)
reports      read models: the class dashboard, exports, a student's course page, chart series, the audit log

errors       the domain error tree               sending      what services need of the task queue (a protocol)
"""
