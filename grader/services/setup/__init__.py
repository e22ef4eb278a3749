"""A course's set-up by its instructors: course settings, the change log, the roster, assignments (dates,
attempts, penalties, extensions, release).

assignments: Assignments: which rubric items one holds, the dates that apply to a student, whether a submission may
  be taken now, how a late attempt's penalty turns its raw score into the counted one, and which items a student
  sees yet; and the instructor's changes to them (create, update, release, extensions), each recorded with who made
  it (grader.services.setup.course_changes).
  public: item_ids, Dates, dates_for, attempts_used, submitted_last_hour, admit, late_text, penalty_fraction,
    Counted, counted_score, counted_grades, counted_public, counted_for, attempts_by_student, assignment_of,
    of_course, checked, checked_extension, create, submission_count, update, release, extension_of, grant_extension,
    revoke_extension, AttemptRow, StudentRow, students_view
course_changes: The record of a course's set-up changes: who changed what and when.
  public: ChangeKind, record, of_course
courses: A course's settings: its time zone (times stay stored in UTC; pages and refusal messages show them in it)
  and whether its students may submit outside an assignment (grader.services.submissions.submit.submit).
  public: update_settings
roster: Roster import: a course's students from CSV (student id, name, email), each new one given a token once, and
  on request each student in the file a fresh sign-in link (grader.services.identity.sign_in_links); each import
  recorded with who made it (grader.services.setup.course_changes), by an instructor of the course only (checked
  here, not only by the page or route).
  public: parse_roster, import_roster, role_conflicts, import_csv, students, issued_csv
"""
