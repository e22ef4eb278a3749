"""A case run's evidence (arrays .npz, spec, provenance, metrics, captured output) is stored in the database
(case_evidence), so a worker's artifacts folder becomes a cache its host may lose. Existing evidence is moved in from
the folders that still exist; a run whose folder is gone gets an event saying so, and no row.

Revision ID: 0017
Revises: 0016
Create Date: 2026-11-26 14:00:00
"""

import json
import logging
from pathlib import Path

import sqlalchemy as sa
from alembic import op

from grader.core import clock  # the service's one "now", shifted with it


revision = '0017'
down_revision = '0016'
branch_labels = None
depends_on = None

# settings.evidence_output_max_bytes' default, fixed here: a migration never changes.
OUTPUT_MAX_BYTES = 1_000_000
FILES = ("arrays.npz", "provenance.json", "metrics.json", "spec.json", "stdout.txt", "stderr.txt")


def upgrade() -> None:
    op.create_table('case_evidence',
    sa.Column('case_run_id', sa.Integer(), nullable=False),
    sa.Column('arrays', sa.LargeBinary(), nullable=True),
    sa.Column('spec', sa.JSON(), nullable=False),
    sa.Column('provenance', sa.JSON(), nullable=True),
    sa.Column('metrics', sa.JSON(), nullable=True),
    sa.Column('stdout', sa.Text(), nullable=True),
    sa.Column('stderr', sa.Text(), nullable=True),
    sa.Column('sizes', sa.JSON(), nullable=False),
    sa.Column('stored_at', sa.DateTime(), nullable=False),
    sa.ForeignKeyConstraint(['case_run_id'], ['case_runs.id'], ),
    sa.PrimaryKeyConstraint('case_run_id')
    )
    _move_evidence_in(op.get_bind())


def downgrade() -> None:
    # Evidence stored after the upgrade has no folder to go back to: it is dropped with the table.
    op.drop_table('case_evidence')


def _move_evidence_in(bind) -> None:
    """One row per finished run that measured its own case (a reused run reads its measurement's run's row)."""
    evidence = sa.table('case_evidence', sa.column('case_run_id', sa.Integer), sa.column('arrays', sa.LargeBinary),
                        *(sa.column(c, sa.JSON) for c in ('spec', 'provenance', 'metrics', 'sizes')),
                        sa.column('stdout', sa.Text), sa.column('stderr', sa.Text), sa.column('stored_at', sa.DateTime))
    events = sa.table('events', sa.column('submission_id', sa.Integer), sa.column('case_run_id', sa.Integer),
                      sa.column('state', sa.String), sa.column('detail', sa.Text), sa.column('at', sa.DateTime))
    runs = bind.execute(sa.text(
        "SELECT id, submission_id, spec, provenance, metrics, artifact_dir FROM case_runs "
        "WHERE artifact_dir IS NOT NULL AND reused_from_id IS NULL AND status IN ('done', 'failed') ORDER BY id"
    )).all()
    now = clock.now()
    moved = missing = 0
    for run_id, submission_id, spec, provenance, metrics, artifact_dir in runs:
        folder = Path(artifact_dir)
        if not folder.is_dir():
            missing += 1
            bind.execute(events.insert().values(
                submission_id=submission_id, case_run_id=run_id, state="evidence", at=now,
                detail=f"migration 0017: evidence folder {artifact_dir} was missing on this host; none stored"))
            continue
        row = _row(folder, spec=_json(spec), provenance=_json(provenance), metrics=_json(metrics))
        bind.execute(evidence.insert().values(case_run_id=run_id, stored_at=now, **row))
        moved += 1
    logging.getLogger("alembic.runtime.migration").info(
        "evidence of %d case runs moved into the database; %d folders missing (an event on each)", moved, missing)


def _json(value):
    return json.loads(value) if isinstance(value, str) else value


def _row(folder: Path, *, spec, provenance, metrics) -> dict:
    """What the folder holds, as grader.core.lifecycle stores it; the run's columns where a JSON file is absent."""
    def text(name: str) -> str | None:
        path = folder / name
        if not path.is_file():
            return None
        data = path.read_bytes()
        if len(data) <= OUTPUT_MAX_BYTES:
            return data.decode(errors="replace")
        return (f"[the first {len(data) - OUTPUT_MAX_BYTES} of {len(data)} bytes were cut; the last "
                f"{OUTPUT_MAX_BYTES} are kept]\n" + data[-OUTPUT_MAX_BYTES:].decode(errors="replace"))

    def read_json(name: str, fallback):
        path = folder / name
        return json.loads(path.read_text()) if path.is_file() else fallback

    arrays = (folder / "arrays.npz").read_bytes() if (folder / "arrays.npz").is_file() else None
    row = dict(arrays=arrays, spec=read_json("spec.json", spec), provenance=read_json("provenance.json", provenance),
               metrics=read_json("metrics.json", metrics), stdout=text("stdout.txt"), stderr=text("stderr.txt"))
    served = {"arrays.npz": arrays, "stdout.txt": row["stdout"], "stderr.txt": row["stderr"],
              **{f"{k}.json": row[k] for k in ("spec", "provenance", "metrics")}}
    row["sizes"] = {name: len(body if isinstance(body, bytes) else
                              (body if name.endswith(".txt") else json.dumps(body, indent=2)).encode())
                    for name in FILES if (body := served[name]) is not None}
    return row
