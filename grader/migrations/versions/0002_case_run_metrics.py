"""Metrics computed once where a case ran, stored with the case run and its reusable measurement.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-23 06:00:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('case_runs', sa.Column('metrics', sa.JSON(), nullable=True))
    op.add_column('measurements', sa.Column('metrics', sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column('measurements', 'metrics')
    op.drop_column('case_runs', 'metrics')
