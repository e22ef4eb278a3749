"""Assignments on real PostgreSQL: the migrations create exactly the models there (and 0008-0006 go down and up
again), and the acceptance tests of tests/grader/services/setup/test_assignments.py (a checkpoint sheet graded with no case run on the
lesson's measured cases, or queueing them where none was measured; hard close, attempt limit, late penalty beside the
raw score, extension) and test_assignment_visibility.py (an item hidden until release then shown with the same score,
the hourly limit) run again on the in-process app with DATABASE_URL pointed at PostgreSQL."""

from __future__ import annotations

import pytest

from tests import services
from tests.grader.conftest import app_on, lesson_measured  # noqa: F401 - the fixture, for the tests below
from tests.grader.services.setup.test_assignments import (  # noqa: F401 - collected here again, against PostgreSQL
    lesson_cases_stored,
    test_a_checkpoint_submission_on_a_service_that_never_measured_the_lesson_queues_its_cases,
    test_a_checkpoint_submission_runs_no_case_and_is_graded_at_once_on_its_items_only,
    test_a_checkpoint_submission_with_one_lesson_case_never_measured_queues_it,
    test_a_late_attempt_is_penalized_per_day_and_the_export_shows_raw_beside_counted,
    test_an_extension_lets_one_student_submit_after_the_close,
    test_before_open_after_close_and_beyond_attempts_are_refused_with_the_rule_and_time,
    test_scores_and_feedback_are_withheld_from_the_student_until_visible,
    test_the_counted_attempt_is_the_latest_or_the_best,
    test_two_submissions_racing_for_one_attempt_number_let_one_in,
)
from tests.grader.services.submissions.test_assignment_visibility import (  # noqa: F401 - collected here again, against PostgreSQL
    test_a_withheld_item_is_hidden_everywhere_a_student_looks_then_shown_on_release_with_the_same_score,
    test_each_submission_says_its_raw_penalty_counted_score_and_whether_it_counts,
    test_submissions_past_the_hourly_limit_get_429_with_retry_after_naming_the_rule,
)
from tests.grader.services.setup.test_course_settings import (  # noqa: F401 - collected here again, against PostgreSQL
    test_refusals_and_pages_show_times_in_the_course_zone,
)

pytestmark = pytest.mark.integration


@pytest.fixture
def database_url():
    with services.postgres_database() as url:
        yield url


@pytest.fixture
def api(database_url, tmp_path, monkeypatch):
    """The `api` fixture of tests/grader, on a fresh PostgreSQL database."""
    with app_on(database_url, tmp_path, monkeypatch) as state:
        yield state


def test_the_migration_creates_exactly_the_models_on_postgresql(database_url):
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from grader.core.db import make_engine, migrate
    from grader.core.models import Base

    migrate(database_url)
    engine = make_engine(database_url)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == []


def test_migrations_0006_to_0008_go_down_and_up_keeping_the_courses(database_url):
    from tests.grader.core.test_storage import down_to_0005_and_up

    down_to_0005_and_up(database_url)
