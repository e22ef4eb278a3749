"""Scores to send to an LMS gradebook, with their attempts and errors: one lti_outbox row per assignment whose
counted scores changed, due for the reconciler's next pass or backing off after a failure.

Revision ID: 0022
Revises: 0021
Create Date: 2026-11-26 03:20:00
"""

import sqlalchemy as sa
from alembic import op


revision = '0022'
down_revision = '0021'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table('lti_outbox',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('assignment_id', sa.Integer(), nullable=False),
    sa.Column('changed_at', sa.DateTime(), nullable=False),
    sa.Column('due_at', sa.DateTime(), nullable=True),
    sa.Column('attempts', sa.Integer(), nullable=False),
    sa.Column('tried_at', sa.DateTime(), nullable=True),
    sa.Column('last_error', sa.Text(), nullable=True),
    sa.Column('waiting', sa.Text(), nullable=True),
    sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('assignment_id')
    )
    with op.batch_alter_table('lti_outbox') as batch_op:
        batch_op.create_index(batch_op.f('ix_lti_outbox_due_at'), ['due_at'], unique=False)


def downgrade() -> None:
    with op.batch_alter_table('lti_outbox') as batch_op:
        batch_op.drop_index(batch_op.f('ix_lti_outbox_due_at'))
    op.drop_table('lti_outbox')
