"""A published rubric version belongs to its publisher's course: unique per (course, lesson, version); the shipped ones
(no course) stay unique per (lesson, version) through a partial index, since a unique constraint treats NULLs as
distinct.

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-26 10:00:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0013'
down_revision = '0012'
branch_labels = None
depends_on = None

# 0003 created UNIQUE (lesson, version) without a name: PostgreSQL named it, SQLite's batch mode names it here.
SQLITE_NAMES = {"uq": "uq_%(table_name)s_%(column_0_name)s"}


def _old_unique_name() -> str:
    return "rubric_versions_lesson_version_key" if op.get_bind().dialect.name == "postgresql" else "uq_rubric_versions_lesson"


def upgrade() -> None:
    with op.batch_alter_table('rubric_versions', naming_convention=SQLITE_NAMES) as batch_op:
        batch_op.add_column(sa.Column('course_id', sa.Integer(), nullable=True))
        batch_op.create_foreign_key('fk_rubric_versions_course_id', 'courses', ['course_id'], ['id'])
        batch_op.create_index(batch_op.f('ix_rubric_versions_course_id'), ['course_id'], unique=False)
        batch_op.drop_constraint(_old_unique_name(), type_='unique')
        batch_op.create_unique_constraint('uq_rubric_versions_course', ['course_id', 'lesson', 'version'])
    op.execute("UPDATE rubric_versions SET course_id = (SELECT users.course_id FROM users "
               "WHERE users.id = rubric_versions.published_by_id) WHERE published_by_id IS NOT NULL")
    op.create_index('uq_rubric_versions_shipped', 'rubric_versions', ['lesson', 'version'], unique=True,
                    postgresql_where=sa.text('course_id IS NULL'), sqlite_where=sa.text('course_id IS NULL'))


def downgrade() -> None:
    # Fails on the restored UNIQUE (lesson, version) if two courses published the same version: nothing is dropped.
    op.drop_index('uq_rubric_versions_shipped', table_name='rubric_versions')
    with op.batch_alter_table('rubric_versions', naming_convention=SQLITE_NAMES) as batch_op:
        batch_op.drop_constraint('uq_rubric_versions_course', type_='unique')
        batch_op.drop_index(batch_op.f('ix_rubric_versions_course_id'))
        batch_op.drop_constraint('fk_rubric_versions_course_id', type_='foreignkey')
        batch_op.drop_column('course_id')
        batch_op.create_unique_constraint(_old_unique_name(), ['lesson', 'version'])
