"""Per-student lab variants (issue 34): an assignment's variant pool, its drawn variants (kept or dropped with the
reason), the one variant fixed per (assignment, student), copy evidence, and the variant a submission is graded under.

Submissions.variant_id is nullable: free submissions and assignments without a pool keep NULL and grade exactly as
before. Downgrade drops the column and the four tables (the pools and their evidence are lost with them).

Revision ID: 0024
Revises: 0023
Create Date: 2026-11-27 11:33:07
"""

import sqlalchemy as sa
from alembic import op


revision = '0024'
down_revision = '0023'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table('variant_pools',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('assignment_id', sa.Integer(), nullable=False),
    sa.Column('lesson', sa.String(length=16), nullable=False),
    sa.Column('space_version', sa.String(length=32), nullable=False),
    sa.Column('space_hash', sa.String(length=64), nullable=False),
    sa.Column('rubric_version', sa.String(length=32), nullable=False),
    sa.Column('seed', sa.Integer(), nullable=False),
    sa.Column('k', sa.Integer(), nullable=False),
    sa.Column('state', sa.String(length=16), nullable=False),
    sa.Column('rejected', sa.JSON(), nullable=False),
    sa.Column('created_by_id', sa.Integer(), nullable=False),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.Column('ready_at', sa.DateTime(), nullable=True),
    sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
    sa.ForeignKeyConstraint(['created_by_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('assignment_id')
    )
    op.create_table('pool_variants',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('pool_id', sa.Integer(), nullable=False),
    sa.Column('name', sa.String(length=32), nullable=False),
    sa.Column('position', sa.Integer(), nullable=False),
    sa.Column('parameters', sa.JSON(), nullable=False),
    sa.Column('digest', sa.String(length=16), nullable=False),
    sa.Column('state', sa.String(length=16), nullable=False),
    sa.Column('reason', sa.Text(), nullable=True),
    sa.Column('submission_id', sa.Integer(), nullable=True),
    sa.Column('check', sa.JSON(), nullable=True),
    sa.Column('decided_at', sa.DateTime(), nullable=True),
    sa.ForeignKeyConstraint(['pool_id'], ['variant_pools.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('pool_id', 'name')
    )
    with op.batch_alter_table('pool_variants', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_pool_variants_pool_id'), ['pool_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_pool_variants_submission_id'), ['submission_id'], unique=False)

    op.create_table('student_variants',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('assignment_id', sa.Integer(), nullable=False),
    sa.Column('student_id', sa.Integer(), nullable=False),
    sa.Column('variant_id', sa.Integer(), nullable=False),
    sa.Column('assigned_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['assignment_id'], ['assignments.id'], ),
    sa.ForeignKeyConstraint(['student_id'], ['users.id'], ),
    sa.ForeignKeyConstraint(['variant_id'], ['pool_variants.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('assignment_id', 'student_id')
    )
    with op.batch_alter_table('student_variants', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_student_variants_assignment_id'), ['assignment_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_student_variants_student_id'), ['student_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_student_variants_variant_id'), ['variant_id'], unique=False)

    op.create_table('copy_flags',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('submission_id', sa.Integer(), nullable=False),
    sa.Column('grade_id', sa.Integer(), nullable=False),
    sa.Column('variant_id', sa.Integer(), nullable=False),
    sa.Column('items', sa.JSON(), nullable=False),
    sa.Column('own_expected', sa.JSON(), nullable=False),
    sa.Column('other_expected', sa.JSON(), nullable=False),
    sa.Column('summary', sa.Text(), nullable=False),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['grade_id'], ['grades.id'], ),
    sa.ForeignKeyConstraint(['submission_id'], ['submissions.id'], ),
    sa.ForeignKeyConstraint(['variant_id'], ['pool_variants.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    with op.batch_alter_table('copy_flags', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_copy_flags_submission_id'), ['submission_id'], unique=False)

    with op.batch_alter_table('submissions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('variant_id', sa.Integer(), nullable=True))
        batch_op.create_index(batch_op.f('ix_submissions_variant_id'), ['variant_id'], unique=False)
        batch_op.create_foreign_key('fk_submissions_variant_id', 'pool_variants', ['variant_id'], ['id'])



def downgrade() -> None:
    with op.batch_alter_table('submissions', schema=None) as batch_op:
        batch_op.drop_constraint('fk_submissions_variant_id', type_='foreignkey')
        batch_op.drop_index(batch_op.f('ix_submissions_variant_id'))
        batch_op.drop_column('variant_id')

    with op.batch_alter_table('copy_flags', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_copy_flags_submission_id'))

    op.drop_table('copy_flags')
    with op.batch_alter_table('student_variants', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_student_variants_variant_id'))
        batch_op.drop_index(batch_op.f('ix_student_variants_student_id'))
        batch_op.drop_index(batch_op.f('ix_student_variants_assignment_id'))

    op.drop_table('student_variants')
    with op.batch_alter_table('pool_variants', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_pool_variants_submission_id'))
        batch_op.drop_index(batch_op.f('ix_pool_variants_pool_id'))

    op.drop_table('pool_variants')
    op.drop_table('variant_pools')
