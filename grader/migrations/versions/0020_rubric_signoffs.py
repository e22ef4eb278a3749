"""Instructor sign-offs of rubric versions: who signed which version's content off for their course, when, and why.

A sign-off is a row of its own, never a change to the version it signs: a published version's content and hash stay
what they were. It names the content hash it signed, so a shipped version whose (unused) file was later replaced
does not carry the old sign-off over to new content.

Revision ID: 0020
Revises: 0019
Create Date: 2026-11-26 03:20:00
"""

import sqlalchemy as sa
from alembic import op


revision = '0020'
down_revision = '0019'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'rubric_signoffs',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('version_id', sa.Integer(), sa.ForeignKey('rubric_versions.id'), nullable=False),
        sa.Column('course_id', sa.Integer(), sa.ForeignKey('courses.id'), nullable=False),
        sa.Column('content_hash', sa.String(length=64), nullable=False),
        sa.Column('user_id', sa.Integer(), sa.ForeignKey('users.id'), nullable=False),
        sa.Column('at', sa.DateTime(), nullable=False),
        sa.Column('note', sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint('id'),
    )
    op.create_index('ix_rubric_signoffs_version_id', 'rubric_signoffs', ['version_id'])
    op.create_index('ix_rubric_signoffs_course_id', 'rubric_signoffs', ['course_id'])


def downgrade() -> None:
    op.drop_index('ix_rubric_signoffs_course_id', table_name='rubric_signoffs')
    op.drop_index('ix_rubric_signoffs_version_id', table_name='rubric_signoffs')
    op.drop_table('rubric_signoffs')
