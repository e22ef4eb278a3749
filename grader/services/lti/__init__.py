"""The LMS: LTI 1.3 registrations, keys, launches and deep links (launch), scores sent to the LMS on their own
(outbox), the roster synced from the LMS (roster).

launch: LTI 1.3 as a tool: platform registrations, the tool's own keys, the one-time OIDC state and nonce, who a
  validated launch signs in, the assignment a deep link opens, the counted scores sent back (AGS).
  public: LaunchRefused, create_registration, course_registrations, signing_key, rotate_key, public_jwks,
    RegistrationConf, LaunchStates, admit_login, forget_launch_states, record_login, fetch_key_set, failure_text,
    Landing, role_of, sign_in, hold_deep_link, pending_deep_link, answer_deep_link, ScoreSent, send_scores,
    token_scopes
outbox: Scores sent to the LMS gradebooks on their own: what changed is marked in the change's transaction
  (`scores_changed`, the core's half), the reconciler's pass sends what is due (`send_due`), a failure backs off and
  stays visible on the instructor's LTI page (`course_overview`), and an instructor may retry at once (`retry_now`).
  public: backoff, OutboxPass, send_due, retry_now, ScoreRow, LineItemRow, LtiOverview, course_overview
roster: The roster from the LMS (NRPS): a course's students as its LMS courses list them, read a page at a time
  (at most settings.lti_roster_max_members members) and written in short batches.
  public: RosterSync, sync_roster
"""
