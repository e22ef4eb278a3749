"""A student's sheet from form to grade: submit, the sheet models and form, drafts, progress, what a reader may
see of a grade (visibility), an instructor's overrides and a student's review requests.

drafts: Drafts: a student's unsent sheet for an assignment (or their free sheet), kept on the server as they type,
  within the sheet's caps (grader.services.submissions.sheets) and the person's draft-save quota
  (settings.rate_limit_draft_saves).
  public: load, save, last_submitted
overrides: Manual overrides: an instructor sets one item's score on one submission, with a required comment.
  public: OverridePublic, override_history, recent_overrides, public, check_override, set_override
progress: A submission's progress while it is graded: where each of its case runs waits in its backend's queue
  (counted from the database), how long its cases took when they were measured before, and each run's state; read by
  the progress page and its polled JSON (grader.pages.submissions.progress).
  public: RunProgress, WarmingUp, Progress, submission_progress, warming_up, queue_order, as_json
review_requests: Review requests: a student asks an instructor to review one item of their graded submission, with a
  message; an instructor answers, with or without an override (grader.services.submissions.overrides), and the
  student reads the answer on the report.
  public: ReviewRequestPublic, state_of, public, ask, request_of, answer, course_requests, submission_requests
sheet_form: The prediction sheet as a form: its inputs generated from the sheet's typed model (rubric.sheet) and the
  lesson's rubric, never written per question; form values to the sheet the API takes and back; the same validation
  as a submission (grader.services.submissions.sheets); the configs' field-by-field difference from the lesson's
  baseline.
  public: Input, ItemForm, answer_inputs, item_forms, config_baseline, flatten, config_values, config_inputs,
    sheet_from_form, form_state, problems, by_input, ConfigCheck, config_checks, sheet_from_yaml, sheet_yaml,
    has_configs
sheets: The service layer's door to the rubric's prediction sheets: bound one's size before any work, parse one,
  list the cases it needs measured, tell a checkpoint sheet apart.
  public: size_problems, check_size, parse_sheet, cases_to_run, checkpoints_only
submit: Submissions: storing one with its case runs, taking one through its assignment's rules, listing what a user
  may read.
  public: create_submission, visible_submissions, submit
visibility: What a user may see of a grade: the one rule, used by the API, the pages and every export.
  public: visibility_of, withheld_items, next_shown_at, deciding_runs, withheld_runs, measurement_twins, shown_report,
    GradeView, grade_view, attempt_standing
"""
