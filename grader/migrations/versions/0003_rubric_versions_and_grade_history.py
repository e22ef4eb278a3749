"""Rubric versions as rows, committed regrades, and grade history (several grades per submission, one current).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23 18:00:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0003'
down_revision = '0002'
branch_labels = None
depends_on = None

# 0001 created grades.submission_id UNIQUE without a name: PostgreSQL named it, SQLite's batch mode names it here.
SQLITE_NAMES = {"uq": "uq_%(table_name)s_%(column_0_name)s"}


def _old_unique_name() -> str:
    return "grades_submission_id_key" if op.get_bind().dialect.name == "postgresql" else "uq_grades_submission_id"


def upgrade() -> None:
    op.create_table('rubric_versions',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('lesson', sa.String(length=16), nullable=False),
    sa.Column('version', sa.String(length=32), nullable=False),
    sa.Column('content_hash', sa.String(length=64), nullable=False),
    sa.Column('content', sa.JSON(), nullable=False),
    sa.Column('source', sa.String(length=16), nullable=False),
    sa.Column('published_by_id', sa.Integer(), nullable=True),
    sa.Column('published_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['published_by_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('lesson', 'version')
    )
    op.create_table('regrades',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('course_id', sa.Integer(), nullable=False),
    sa.Column('lesson', sa.String(length=16), nullable=False),
    sa.Column('version', sa.String(length=32), nullable=False),
    sa.Column('committed_by_id', sa.Integer(), nullable=False),
    sa.Column('committed_at', sa.DateTime(), nullable=False),
    sa.Column('regraded', sa.Integer(), nullable=False),
    sa.Column('changed', sa.Integer(), nullable=False),
    sa.Column('skipped', sa.JSON(), nullable=False),
    sa.ForeignKeyConstraint(['committed_by_id'], ['users.id'], ),
    sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    op.create_index(op.f('ix_regrades_course_id'), 'regrades', ['course_id'], unique=False)
    with op.batch_alter_table('grades', naming_convention=SQLITE_NAMES) as batch_op:
        batch_op.drop_constraint(_old_unique_name(), type_='unique')
        batch_op.add_column(sa.Column('superseded_at', sa.DateTime(), nullable=True))
        batch_op.add_column(sa.Column('regrade_id', sa.Integer(), nullable=True))
        batch_op.create_foreign_key('fk_grades_regrade_id', 'regrades', ['regrade_id'], ['id'])
        batch_op.create_index(batch_op.f('ix_grades_submission_id'), ['submission_id'], unique=False)
    # At most one current grade per submission: the guard against grading twice, now that history is kept.
    op.create_index('uq_grades_current', 'grades', ['submission_id'], unique=True,
                    postgresql_where=sa.text('superseded_at IS NULL'), sqlite_where=sa.text('superseded_at IS NULL'))


def downgrade() -> None:
    op.drop_index('uq_grades_current', table_name='grades')
    with op.batch_alter_table('grades', naming_convention=SQLITE_NAMES) as batch_op:
        batch_op.drop_index(batch_op.f('ix_grades_submission_id'))
        batch_op.drop_constraint('fk_grades_regrade_id', type_='foreignkey')
        batch_op.drop_column('regrade_id')
        batch_op.drop_column('superseded_at')
        batch_op.create_unique_constraint(_old_unique_name(), ['submission_id'])
    op.drop_index(op.f('ix_regrades_course_id'), table_name='regrades')
    op.drop_table('regrades')
    op.drop_table('rubric_versions')
