"""Whether a course's students may submit outside an assignment; existing courses keep allowing it.

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-26 09:00:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0012'
down_revision = '0011'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('courses') as batch_op:
        batch_op.add_column(sa.Column('free_submissions', sa.Boolean(), server_default=sa.text('true'),
                                      nullable=False))


def downgrade() -> None:
    with op.batch_alter_table('courses') as batch_op:
        batch_op.drop_column('free_submissions')
