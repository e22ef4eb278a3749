"""Variant pools an instructor can rely on (issue 47): K is the number of variants to keep, `draw_budget` the most
variants the pool may draw and measure to keep them, `minimum` how many must be kept before students get one.

Both nullable: a pool made before this revision drew exactly K (its budget is K) and served students once ready
(its minimum is K); grader.core.variants reads NULL so. Downgrade drops the two columns.

Revision ID: 0025
Revises: 0024
Create Date: 2026-12-07 23:05:00
"""

import sqlalchemy as sa
from alembic import op


revision = '0025'
down_revision = '0024'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('variant_pools') as batch:
        batch.add_column(sa.Column('draw_budget', sa.Integer(), nullable=True))
        batch.add_column(sa.Column('minimum', sa.Integer(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('variant_pools') as batch:
        batch.drop_column('minimum')
        batch.drop_column('draw_budget')
