"""Every change an instructor makes to a course's set-up, with who and when.

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-26 03:20:00
"""

import sqlalchemy as sa  # noqa: F401
from alembic import op  # noqa: F401


revision = '0019'
down_revision = '0018'
branch_labels = None
depends_on = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
