"""Rubric versions of a course: the tolerance review and sign-off, the regrade preview and commit.

regrade: Regrade a course's lesson under another rubric version: preview per student (nothing written), then commit.
  public: ItemDiff, RegradeEntry, RegradePreview, RegradeRecord, record, preview_regrade, commit_regrade,
    regrade_records, rubric_versions
tolerance_review: A rubric version's tolerance review for one course: each tolerance beside what the course
  measured, the instructors' sign-offs of the version, and a new version drafted from an old one's tolerances and
  published.
  public: SignoffRecord, VersionReview, signoffs, pending_signoffs, signoff_states, version_review, sign_off,
    DraftTolerance, Draft, draft_from, publish_draft
"""
