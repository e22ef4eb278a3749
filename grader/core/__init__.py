"""The neutral core of the grading service: database sessions (db), run-state changes (lifecycle), token security.

With grader.settings and grader.models, the only part of grader that worker/ imports.
"""
