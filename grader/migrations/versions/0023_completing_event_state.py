"""The event state "figures" is renamed "completing": the service draws nothing when a grade completes, it only adds
the lab check (worker.grading.complete_grade).

Stored "figures" events are of two kinds, both steps of completing a stored grade: the reconciler's note that it
re-sent the grade task of a grade still missing its lab check (grader/reconcile.py), and, before issue 24, the
worker's note that it had drawn the grade's PNGs. Both become "completing", so the events API names one state for
it; the detail of each row is kept as written. Downgrade turns every "completing" back into "figures" (the state
the code before this revision writes for the same re-send).

Revision ID: 0023
Revises: 0022
Create Date: 2026-11-27 11:30:00
"""

from alembic import op


revision = '0023'
down_revision = '0022'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.execute("UPDATE events SET state = 'completing' WHERE state = 'figures'")


def downgrade() -> None:
    op.execute("UPDATE events SET state = 'figures' WHERE state = 'completing'")
