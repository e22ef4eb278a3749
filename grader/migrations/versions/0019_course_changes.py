"""Every change an instructor makes to a course's set-up, with who and when.

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-26 03:20:00
"""

import sqlalchemy as sa
from alembic import op


revision = '0019'
down_revision = '0018'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table('course_changes',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('course_id', sa.Integer(), nullable=False),
    sa.Column('by_id', sa.Integer(), nullable=False),
    sa.Column('at', sa.DateTime(), nullable=False),
    sa.Column('kind', sa.String(length=32), nullable=False),
    sa.Column('assignment_id', sa.Integer(), nullable=True),
    sa.Column('summary', sa.Text(), nullable=False),
    sa.Column('detail', sa.JSON(), nullable=False),
    sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
    sa.ForeignKeyConstraint(['by_id'], ['users.id'], ),
    sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    with op.batch_alter_table('course_changes') as batch_op:
        batch_op.create_index(batch_op.f('ix_course_changes_assignment_id'), ['assignment_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_course_changes_course_id'), ['course_id'], unique=False)


def downgrade() -> None:
    with op.batch_alter_table('course_changes') as batch_op:
        batch_op.drop_index(batch_op.f('ix_course_changes_course_id'))
        batch_op.drop_index(batch_op.f('ix_course_changes_assignment_id'))
    op.drop_table('course_changes')
