"""The neutral core of the grading service, shared by the services, the web layer and the worker:

models       the tables (SQLAlchemy)                     settings     the service's settings, from the environment
grades       a submission's current grade and history
db           the engine, sessions and migrations         states       the enums of every state machine and vocabulary
lifecycle    every state change of a case run or a       grading      scoring a submission and storing its grade
             submission (claim, store, requeue, resend)  content_key  the key a stored measurement is reused by
rubrics      rubric versions and a course's current one  lab_check    the lab check of a submission's own runs
audit        the audit log's vocabulary and re-runs      timezones    course time zones
security     token hashing                               clock        the one "now" (frozen by tests, shifted by settings)
outbound     every URL the server fetches, under one policy (https, public addresses, no redirects, size and time caps)

The only part of grader that worker/ imports; it imports no service, web layer or worker module (import-linter contract core-neutral in pyproject.toml).
"""
