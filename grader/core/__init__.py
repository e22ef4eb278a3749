"""Infrastructure of the grading service: database engine and sessions, token security."""
