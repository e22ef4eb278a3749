"""Assignments: what a course asks for one lesson (items, dates, late policy, attempts, visibility), per-student
extensions, and each submission's assignment, attempt number and lateness.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-23 19:00:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0005'
down_revision = '0004'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table('assignments',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('course_id', sa.Integer(), nullable=False),
    sa.Column('title', sa.String(length=128), nullable=False),
    sa.Column('lesson', sa.String(length=16), nullable=False),
    sa.Column('items', sa.String(length=16), nullable=False),
    sa.Column('open_at', sa.DateTime(), nullable=False),
    sa.Column('due_at', sa.DateTime(), nullable=False),
    sa.Column('hard_close_at', sa.DateTime(), nullable=False),
    sa.Column('late_penalty_per_day', sa.Float(), nullable=False),
    sa.Column('late_penalty_cap', sa.Float(), nullable=True),
    sa.Column('max_attempts', sa.Integer(), nullable=True),
    sa.Column('counted_attempt', sa.String(length=8), nullable=False),
    sa.Column('visibility', sa.String(length=16), nullable=False),
    sa.Column('released_at', sa.DateTime(), nullable=True),
    sa.Column('created_by_id', sa.Integer(), nullable=False),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
    sa.ForeignKeyConstraint(['created_by_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    op.create_index(op.f('ix_assignments_course_id'), 'assignments', ['course_id'], unique=False)
    op.create_table('extensions',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('assignment_id', sa.Integer(), nullable=False),
    sa.Column('student_id', sa.Integer(), nullable=False),
    sa.Column('due_at', sa.DateTime(), nullable=False),
    sa.Column('hard_close_at', sa.DateTime(), nullable=False),
    sa.Column('granted_by_id', sa.Integer(), nullable=False),
    sa.Column('granted_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
    sa.ForeignKeyConstraint(['granted_by_id'], ['users.id'], ),
    sa.ForeignKeyConstraint(['student_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('assignment_id', 'student_id')
    )
    op.create_index(op.f('ix_extensions_assignment_id'), 'extensions', ['assignment_id'], unique=False)
    with op.batch_alter_table('users') as batch_op:
        batch_op.add_column(sa.Column('full_name', sa.String(length=128), nullable=True))
        batch_op.add_column(sa.Column('email', sa.String(length=254), nullable=True))
    with op.batch_alter_table('submissions') as batch_op:
        batch_op.add_column(sa.Column('assignment_id', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('attempt', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('late_seconds', sa.Integer(), nullable=True))
        batch_op.create_index(batch_op.f('ix_submissions_assignment_id'), ['assignment_id'], unique=False)
        batch_op.create_foreign_key('fk_submissions_assignment_id', 'assignments', ['assignment_id'], ['id'])
        batch_op.create_unique_constraint('uq_submissions_assignment_id_student_id_attempt',
                                          ['assignment_id', 'student_id', 'attempt'])


def downgrade() -> None:
    with op.batch_alter_table('submissions') as batch_op:
        batch_op.drop_constraint('uq_submissions_assignment_id_student_id_attempt', type_='unique')
        batch_op.drop_constraint('fk_submissions_assignment_id', type_='foreignkey')
        batch_op.drop_index(batch_op.f('ix_submissions_assignment_id'))
        batch_op.drop_column('late_seconds')
        batch_op.drop_column('attempt')
        batch_op.drop_column('assignment_id')
    with op.batch_alter_table('users') as batch_op:
        batch_op.drop_column('email')
        batch_op.drop_column('full_name')
    op.drop_index(op.f('ix_extensions_assignment_id'), table_name='extensions')
    op.drop_table('extensions')
    op.drop_index(op.f('ix_assignments_course_id'), table_name='assignments')
    op.drop_table('assignments')
