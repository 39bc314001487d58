"""Start-up schema migration: the rows of the two job tables of schema 1 move into the one job table.

Schema 1 had ``jobs`` (SHRM jobs only: ``envmap_id``, ``brdf_id``, ``brdf_spec``, ``params`` columns) and
``analyses`` (tradeoff sweeps and scenes: ``kind``, ``request``, ``result``). Schema 2 has one ``jobs`` table for
every kind (:class:`relight.server.db.Job`). At start-up (:meth:`relight.server.db.Database.create_all`):

1. a schema-1 ``jobs`` table (no ``kind`` column) is renamed ``jobs_v1`` and its index dropped (the new table's
   index has the same name);
2. the schema-2 tables are created, and columns added since (nullable ones: the job claim's ``owner`` and
   ``lease_until``) are added to an existing ``jobs`` table;
3. every row of ``jobs_v1`` and ``analyses`` is inserted into ``jobs`` (SHRM rows get ``kind = "shrm"`` and their
   inputs as the canonical request; analysis rows keep their kind, request and result), then the old table is
   dropped, in the same transaction.

Ids are kept, so a finished job is found again by the same request (the ids are content hashes of the request, and
the kinds' id rules are those of schema 1). Every step is idempotent: a process killed in between repeats the
missing steps at its next start and rows already copied are skipped, so no job is lost and none is duplicated.
"""

from __future__ import annotations

import logging
from typing import Any

from sqlalchemy import JSON, Column, DateTime, Float, Integer, MetaData, String, Table, Text, inspect, select, text
from sqlalchemy.engine import Connection, Engine

log = logging.getLogger("relight.server")

_legacy = MetaData()

#: Schema 1's SHRM job table (renamed from ``jobs``), exactly as schema 1 declared it.
JOBS_V1 = Table(
    "jobs_v1", _legacy,
    Column("id", String(64), primary_key=True),
    Column("state", String(16)),
    Column("stage", String(64)),
    Column("progress", Float),
    Column("envmap_id", String(64)),
    Column("brdf_id", String(64)),
    Column("brdf_spec", JSON),
    Column("params", JSON),
    Column("predicted", JSON),
    Column("measured", JSON),
    Column("failure_reason", Text),
    Column("retryable", Integer),
    Column("runs", Integer),
    Column("submissions", Integer),
    Column("worker", String(255)),
    Column("result_sha256", String(64)),
    Column("created_at", DateTime(timezone=True)),
    Column("submitted_at", DateTime(timezone=True)),
    Column("started_at", DateTime(timezone=True)),
    Column("finished_at", DateTime(timezone=True)),
    Column("updated_at", DateTime(timezone=True)),
)

#: Schema 1's table of tradeoff sweeps and scenes.
ANALYSES = Table(
    "analyses", _legacy,
    Column("id", String(64), primary_key=True),
    Column("kind", String(16)),
    Column("state", String(16)),
    Column("request", JSON),
    Column("result", JSON),
    Column("failure_reason", Text),
    Column("retryable", Integer),
    Column("created_at", DateTime(timezone=True)),
    Column("finished_at", DateTime(timezone=True)),
)


def _from_jobs_v1(r: Any) -> dict[str, Any]:
    return {
        "id": r.id, "kind": "shrm", "state": r.state, "stage": r.stage, "progress": r.progress or 0.0,
        "request": {"envmap": r.envmap_id, "brdf": r.brdf_id, "brdf_spec": r.brdf_spec, "params": r.params},
        "predicted": r.predicted, "measured": r.measured, "result": None, "result_sha256": r.result_sha256,
        "failure_reason": r.failure_reason, "retryable": r.retryable or 0, "runs": r.runs or 0,
        "submissions": r.submissions or 0, "worker": r.worker, "created_at": r.created_at,
        "submitted_at": r.submitted_at, "started_at": r.started_at, "finished_at": r.finished_at,
        "updated_at": r.updated_at or r.created_at,
    }


def _from_analyses(r: Any) -> dict[str, Any]:
    return {
        "id": r.id, "kind": r.kind, "state": r.state, "stage": r.state,
        "progress": 1.0 if r.state == "succeeded" else 0.0, "request": r.request, "predicted": None,
        "measured": None, "result": r.result, "result_sha256": None, "failure_reason": r.failure_reason,
        "retryable": r.retryable or 0, "runs": 0, "submissions": 0, "worker": None, "created_at": r.created_at,
        "submitted_at": None, "started_at": None, "finished_at": r.finished_at,
        "updated_at": r.finished_at or r.created_at,
    }


def _move(conn: Connection, legacy: Table, jobs: Table, convert: Any) -> int:
    known = set(conn.scalars(select(jobs.c.id)))
    rows = [convert(r) for r in conn.execute(select(legacy)) if r.id not in known]
    if rows:
        conn.execute(jobs.insert(), rows)
    legacy.drop(conn)
    return len(rows)


def _add_columns(engine: Engine, table: Table) -> None:
    """Add the nullable columns ``table`` gained since the database was created (schema 2 -> 3: ``owner`` and
    ``lease_until`` of the job claim); ``create_all`` creates missing tables only."""
    have = {c["name"] for c in inspect(engine).get_columns(table.name)}
    missing = [c for c in table.columns if c.name not in have]
    if not missing:
        return
    with engine.begin() as conn:
        for col in missing:
            if not col.nullable:
                raise RuntimeError(f"cannot add the required column {table.name}.{col.name} to an existing table")
            conn.execute(text(f"ALTER TABLE {table.name} ADD COLUMN {col.name} {col.type.compile(engine.dialect)}"))
    log.warning("added the columns %s to the table %r", ", ".join(c.name for c in missing), table.name)


def migrate(engine: Engine, metadata: MetaData) -> int:
    """Bring the database to the current schema (module docstring); returns the number of rows moved."""
    tables = set(inspect(engine).get_table_names())
    if "jobs" in tables and "kind" not in {c["name"] for c in inspect(engine).get_columns("jobs")}:
        if "jobs_v1" in tables:
            raise RuntimeError("the database holds both a schema-1 'jobs' table and 'jobs_v1' (an interrupted "
                               "migration that something else changed); move one of them away and start again")
        with engine.begin() as conn:
            conn.execute(text("ALTER TABLE jobs RENAME TO jobs_v1"))
            conn.execute(text("DROP INDEX IF EXISTS ix_jobs_state"))
        tables = (tables - {"jobs"}) | {"jobs_v1"}
    metadata.create_all(engine)
    jobs = metadata.tables["jobs"]
    _add_columns(engine, jobs)
    moved = 0
    for legacy, convert in ((JOBS_V1, _from_jobs_v1), (ANALYSES, _from_analyses)):
        if legacy.name in tables:
            with engine.begin() as conn:
                n = _move(conn, legacy, jobs, convert)
            log.warning("migrated %d jobs from the schema-1 table %r into 'jobs'", n, legacy.name)
            moved += n
    return moved
