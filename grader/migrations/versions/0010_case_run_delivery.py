"""A case run's message number is its delivery, not an attempt: a student's attempt is Submission.attempt.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-25 21:00:00
"""

from alembic import op


revision = '0010'
down_revision = '0009'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('case_runs') as batch_op:
        batch_op.alter_column('attempt', new_column_name='delivery')


def downgrade() -> None:
    with op.batch_alter_table('case_runs') as batch_op:
        batch_op.alter_column('delivery', new_column_name='attempt')
