"""A course's time zone (IANA name) for showing its times; existing courses show UTC as before.

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-25 00:42:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0008'
down_revision = '0007'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('courses') as batch_op:
        batch_op.add_column(sa.Column('timezone', sa.String(length=64), server_default='UTC', nullable=False))


def downgrade() -> None:
    with op.batch_alter_table('courses') as batch_op:
        batch_op.drop_column('timezone')
