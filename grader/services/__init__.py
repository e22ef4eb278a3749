"""The service layer: domain operations that take a database session and return typed results or raise
grader.services.errors. The API (grader.api) and the pages (grader.pages) both call these; nothing here imports
FastAPI, Celery or the worker (import-linter contracts in pyproject.toml).

accounts      courses, people and tokens          access       who may do what (roles, courses)
submissions   submit, store, list                 assignments  admission, dates, penalties, counted grades
visibility    what a user may see of a grade      exports      CSV, Gradescope, evidence files
dashboard     the class dashboard, resend         regrade      preview and commit under another rubric version
audit         the discrepancy log, audit re-runs  roster       roster import
courses       course settings                     sheets       the sheet models for the API
errors        the domain error tree               sending      what services need of the task queue
sessions      page sessions (sign-in, sign-out)   quotas       per-person limits on costly requests
sign_in_links students' single-use sign-in links   course_page  a student's course page, as data
lti           LTI 1.3: registrations, keys, launches, deep links, scores sent to the LMS
lti_outbox    scores sent to the LMS on their own: marked on change, sent by the reconciler, retried, shown
overrides     an instructor's score for one item, with its comment, kept beside the measured verdict
review_requests  a student's request to review one item, and the instructor's answer
"""
