"""A limit on one student's submissions to an assignment in any 60 minutes (NULL: none).

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-25 00:41:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0007'
down_revision = '0006'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('assignments') as batch_op:
        batch_op.add_column(sa.Column('max_per_hour', sa.Integer(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('assignments') as batch_op:
        batch_op.drop_column('max_per_hour')
