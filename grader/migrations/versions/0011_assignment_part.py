"""An assignment holds a part of the lesson's sheet (checkpoints, exercises or the whole sheet): the column is its
part, not "items" (a grade's items are the rubric items it scored).

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-25 21:10:00
"""

from alembic import op


revision = '0011'
down_revision = '0010'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('assignments') as batch_op:
        batch_op.alter_column('items', new_column_name='part')


def downgrade() -> None:
    with op.batch_alter_table('assignments') as batch_op:
        batch_op.alter_column('part', new_column_name='items')
