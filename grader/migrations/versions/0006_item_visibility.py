"""Per-item visibility: an assignment may show some items otherwise than its default (after the due date, on
release or at once); existing assignments keep their one setting for every item.

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-25 00:40:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0006'
down_revision = '0005'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('assignments') as batch_op:
        batch_op.add_column(sa.Column('item_visibility', sa.JSON(), server_default='{}', nullable=False))


def downgrade() -> None:
    with op.batch_alter_table('assignments') as batch_op:
        batch_op.drop_column('item_visibility')
