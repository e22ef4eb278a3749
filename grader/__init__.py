"""The grading service: settings, HTTP API, storage, dashboard and the `grader` command line. Never imports Genesis."""
