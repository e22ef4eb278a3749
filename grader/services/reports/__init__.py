"""Read models: the class dashboard, exports (CSV, Gradescope, evidence files), a student's course page, the
report's chart series, the audit log.

audit: The backend-discrepancy audit log: its filters, the entries a course's staff read, the CSV export, and asking
  for an audit re-run of a stored case run on another backend, precision or execution mode.
  public: AuditRerunRequest, Filters, filtered_entries, entry_of, recent_audit_runs, entries_csv, request_rerun
course_page: A student's course page as data: per assignment of the course, the dates that apply to them, what a
  submission now would meet (admitted or refused, how late, the penalty), their attempts and the score that counts
  so far.
  public: AttemptLine, NowLine, AssignmentLine, student_course
dashboard: A course's class dashboard, read from storage once and served both as JSON (/v1) and as the page.
  public: RosterRow, RunProblem, PredictionRow, PredictionPlot, MeasurementGroup, BackendSpread, AssignmentGrades,
    LessonAnalysis, Dashboard, current_grades, latest_graded, case_run_of, resend_case_run, predictions,
    backend_spread, graded_reports, lesson_analyses, course_dashboard, assignment_grades
exports: Grade exports for instructors: a course's grades as CSV, an assignment's counted grades as CSV, one
  submission as Gradescope results.json, and the evidence files of a case run (from the database).
  public: course_grades_csv, override_note, counted_grades_csv, gradescope, evidence_names, evidence_file
series: The report's charts as data: the series its browser charts draw (grader/static/report_charts.js), read from
  the arrays stored in the database, and the list of charts with a text caption of their key numbers.
  public: compact, submission_series, Chart, report_charts
"""
