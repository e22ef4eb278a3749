"""The backend-discrepancy audit log: append-only entries (the database refuses UPDATE and DELETE), audit re-runs.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23 18:30:00
"""

from alembic import op
import sqlalchemy as sa


revision = '0004'
down_revision = '0003'
branch_labels = None
depends_on = None

REFUSAL = "audit entries are append-only"


def upgrade() -> None:
    with op.batch_alter_table('case_runs') as batch_op:
        batch_op.add_column(sa.Column('purpose', sa.String(length=16), server_default='grading', nullable=False))
        batch_op.add_column(sa.Column('mode', sa.String(length=16), nullable=True))
        batch_op.add_column(sa.Column('source_case_run_id', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('requested_by_id', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('spec_key', sa.String(length=64), nullable=True))
        batch_op.create_index(batch_op.f('ix_case_runs_spec_key'), ['spec_key'], unique=False)
        batch_op.create_foreign_key('fk_case_runs_source_case_run_id', 'case_runs', ['source_case_run_id'], ['id'])
        batch_op.create_foreign_key('fk_case_runs_requested_by_id', 'users', ['requested_by_id'], ['id'])
    op.create_table('audit_entries',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('created_at', sa.DateTime(), nullable=False),
    sa.Column('course_id', sa.Integer(), nullable=True),
    sa.Column('lesson', sa.String(length=16), nullable=False),
    sa.Column('case', sa.String(length=64), nullable=False),
    sa.Column('spec_key', sa.String(length=64), nullable=False),
    sa.Column('spec', sa.JSON(), nullable=False),
    sa.Column('left_case_run_id', sa.Integer(), nullable=False),
    sa.Column('right_case_run_id', sa.Integer(), nullable=True),
    sa.Column('left_variant', sa.String(length=48), nullable=False),
    sa.Column('right_variant', sa.String(length=48), nullable=False),
    sa.Column('left_provenance', sa.JSON(), nullable=True),
    sa.Column('right_provenance', sa.JSON(), nullable=True),
    sa.Column('classification', sa.String(length=24), nullable=False),
    sa.Column('summary', sa.Text(), nullable=False),
    sa.Column('comparison', sa.JSON(), nullable=True),
    sa.Column('figures_dir', sa.Text(), nullable=True),
    sa.Column('figures', sa.JSON(), nullable=False),
    sa.Column('requested_by_id', sa.Integer(), nullable=True),
    sa.ForeignKeyConstraint(['course_id'], ['courses.id'], ),
    sa.ForeignKeyConstraint(['left_case_run_id'], ['case_runs.id'], ),
    sa.ForeignKeyConstraint(['right_case_run_id'], ['case_runs.id'], ),
    sa.ForeignKeyConstraint(['requested_by_id'], ['users.id'], ),
    sa.PrimaryKeyConstraint('id')
    )
    for column in ('classification', 'course_id', 'created_at', 'spec_key'):
        op.create_index(op.f(f'ix_audit_entries_{column}'), 'audit_entries', [column], unique=False)
    if op.get_bind().dialect.name == 'postgresql':
        op.execute(f"""
            CREATE FUNCTION audit_entries_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
            BEGIN
                RAISE EXCEPTION '{REFUSAL}: % of entry % refused', TG_OP, OLD.id;
            END $$""")
        op.execute("""CREATE TRIGGER audit_entries_append_only BEFORE UPDATE OR DELETE ON audit_entries
                      FOR EACH ROW EXECUTE FUNCTION audit_entries_append_only()""")
        # TRUNCATE skips row triggers: refuse it too.
        op.execute("""CREATE TRIGGER audit_entries_no_truncate BEFORE TRUNCATE ON audit_entries
                      FOR EACH STATEMENT EXECUTE FUNCTION audit_entries_append_only()""")
    else:
        for action in ('UPDATE', 'DELETE'):
            op.execute(f"""CREATE TRIGGER audit_entries_no_{action.lower()} BEFORE {action} ON audit_entries
                           BEGIN SELECT RAISE(ABORT, '{REFUSAL}: {action} refused'); END""")


def downgrade() -> None:
    if op.get_bind().dialect.name == 'postgresql':
        op.execute("DROP TRIGGER audit_entries_no_truncate ON audit_entries")
        op.execute("DROP TRIGGER audit_entries_append_only ON audit_entries")
        op.execute("DROP FUNCTION audit_entries_append_only()")
    for column in ('spec_key', 'created_at', 'course_id', 'classification'):
        op.drop_index(op.f(f'ix_audit_entries_{column}'), table_name='audit_entries')
    op.drop_table('audit_entries')
    with op.batch_alter_table('case_runs') as batch_op:
        batch_op.drop_constraint('fk_case_runs_requested_by_id', type_='foreignkey')
        batch_op.drop_constraint('fk_case_runs_source_case_run_id', type_='foreignkey')
        batch_op.drop_index(batch_op.f('ix_case_runs_spec_key'))
        batch_op.drop_column('spec_key')
        batch_op.drop_column('requested_by_id')
        batch_op.drop_column('source_case_run_id')
        batch_op.drop_column('mode')
        batch_op.drop_column('purpose')
