"""Students' unsent prediction sheets (drafts), saved by the sheet form as they type: one per user and assignment,
and one free sheet per user.

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-26 14:00:00
"""

import sqlalchemy as sa
from alembic import op


revision = '0016'
down_revision = '0015'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table('drafts',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('user_id', sa.Integer(), nullable=False),
    sa.Column('assignment_id', sa.Integer(), nullable=True),
    sa.Column('sheet', sa.JSON(), nullable=False),
    sa.Column('updated_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
    sa.ForeignKeyConstraint(['user_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('user_id', 'assignment_id')
    )
    with op.batch_alter_table('drafts') as batch_op:
        batch_op.create_index(batch_op.f('ix_drafts_assignment_id'), ['assignment_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_drafts_user_id'), ['user_id'], unique=False)
        batch_op.create_index('uq_drafts_free_sheet', ['user_id'], unique=True,
                              postgresql_where=sa.text('assignment_id IS NULL'),
                              sqlite_where=sa.text('assignment_id IS NULL'))


def downgrade() -> None:
    with op.batch_alter_table('drafts') as batch_op:
        batch_op.drop_index('uq_drafts_free_sheet')
        batch_op.drop_index(batch_op.f('ix_drafts_user_id'))
        batch_op.drop_index(batch_op.f('ix_drafts_assignment_id'))
    op.drop_table('drafts')
