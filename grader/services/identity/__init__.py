"""Who someone is and what they may do: accounts and tokens, page sessions, students' sign-in links, role
decisions (access) and per-person limits (quotas).

access: Who may do what: a student acts on their own submissions, instructors and auditors (staff) read their
  course's, and only instructors change it.
  public: can_read, readable_submission, is_student, is_instructor, is_staff, require_role, require_staff,
    require_instructor, require_course_instructor, own_course
accounts: Courses, people and their API tokens (expiring, revocable).
  public: get_or_create_course, get_or_create_user, create_token, find_token, token_refusal, user_by_token,
    revoke_token, revoke_student_tokens, tokens_of
quotas: Per-person and per-address quotas on costly or guessable work, counted by the `limits` library in
  settings.rate_limit_storage_url (memory:// for one process, Redis when several API processes serve), so every door
  (the API, the pages, the command line through the API) counts against the same store: submissions per person,
  audit re-runs per staff member, draft saves per person, review requests per student, and failed sign-ins and
  unknown sign-in links per client address.
  public: wait_for, rule_text, refusal, take, refuse_while_spent, spend
sessions: Page sign-in sessions: the browser's cookie holds a random 256-bit secret, the table only its sha256; a
  session ends when idle too long, at its absolute expiry (never after its token's), or when revoked (sign-out, its
  token revoked, the sign-in link that opened it re-issued).
  public: open_session, session_user, seen_session, unchanged_until, revoke_session, revoke_link_sessions,
    refuse_failing_address, count_failed_sign_in, revoke_sessions
sign_in_links: Students' sign-in links: a random 256-bit secret in the link, only its sha256 stored; one live link
  per student (issuing another revokes the earlier and ends the page sessions the earlier links opened), used once,
  within settings.sign_in_link_days.
  public: issue, revoke_links, issue_for, find, look_up, refusal, Redeemed, redeem
"""
