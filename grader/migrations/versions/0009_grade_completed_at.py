"""When a grade's lab check (until issue 24 also its PNGs) joined it: the worker stores the score first and completes
it after.

Existing grades were stored with their check (and PNGs) already made, so they are complete when they were made.

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-25 12:40:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0009'
down_revision = '0008'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('grades') as batch_op:
        batch_op.add_column(sa.Column('completed_at', sa.DateTime(), nullable=True))
    op.execute("UPDATE grades SET completed_at = created_at")


def downgrade() -> None:
    with op.batch_alter_table('grades') as batch_op:
        batch_op.drop_column('completed_at')
