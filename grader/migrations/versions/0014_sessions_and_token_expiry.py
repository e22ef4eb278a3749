"""Page sign-ins become server-side sessions (web_sessions: only the sha256 of the cookie's secret), and API tokens
expire: every token made before this migration expires 180 days after it ran (none is left permanent).

Revision ID: 0014
Revises: 0013
Create Date: 2026-11-26 10:00:00
"""

from datetime import timedelta

import sqlalchemy as sa
from alembic import op

from grader.core import clock  # the service's one "now", shifted with it


revision = '0014'
down_revision = '0013'
branch_labels = None
depends_on = None

EXISTING_TOKENS_LAST_DAYS = 180  # settings.token_lifetime_days' default, fixed here: a migration never changes


def upgrade() -> None:
    with op.batch_alter_table('api_tokens') as batch_op:
        batch_op.add_column(sa.Column('expires_at', sa.DateTime(), nullable=True))
    until = clock.now() + timedelta(days=EXISTING_TOKENS_LAST_DAYS)
    op.execute(sa.text("UPDATE api_tokens SET expires_at = :until WHERE expires_at IS NULL").bindparams(until=until))
    op.create_table('web_sessions',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('user_id', sa.Integer(), nullable=False),
    sa.Column('token_id', sa.Integer(), nullable=True),
    sa.Column('secret_hash', sa.String(length=64), nullable=False),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.Column('last_seen_at', sa.DateTime(), nullable=False),
    sa.Column('expires_at', sa.DateTime(), nullable=False),
    sa.Column('revoked_at', sa.DateTime(), nullable=True),
    sa.ForeignKeyConstraint(['token_id'], ['api_tokens.id'], ),
    sa.ForeignKeyConstraint(['user_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id'),
    sa.UniqueConstraint('secret_hash')
    )
    with op.batch_alter_table('web_sessions') as batch_op:
        batch_op.create_index(batch_op.f('ix_web_sessions_token_id'), ['token_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_web_sessions_user_id'), ['user_id'], unique=False)


def downgrade() -> None:
    with op.batch_alter_table('web_sessions') as batch_op:
        batch_op.drop_index(batch_op.f('ix_web_sessions_user_id'))
        batch_op.drop_index(batch_op.f('ix_web_sessions_token_id'))
    op.drop_table('web_sessions')
    with op.batch_alter_table('api_tokens') as batch_op:
        batch_op.drop_column('expires_at')
