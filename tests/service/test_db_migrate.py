"""Start-up migration of a schema-1 database (``relight.server.migrate``): the rows of the old ``jobs`` (SHRM jobs)
and ``analyses`` (sweeps, scenes) tables move into the one job table with every field, none lost, none doubled.

The schema-1 database is built here with schema 1's own DDL (what SQLAlchemy emitted for the old models, verbatim)
and rows written the way schema 1 stored them (JSON text, naive UTC datetimes)."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy import inspect, text

from relight.server.db import Database, Job

SCHEMA_1 = """
CREATE TABLE analyses (
	id VARCHAR(64) NOT NULL, kind VARCHAR(16) NOT NULL, state VARCHAR(16) NOT NULL, request JSON NOT NULL,
	result JSON, failure_reason TEXT, retryable INTEGER NOT NULL, created_at DATETIME NOT NULL, finished_at DATETIME,
	PRIMARY KEY (id)
);
CREATE INDEX ix_analyses_kind ON analyses (kind);
CREATE INDEX ix_analyses_state ON analyses (state);
CREATE TABLE jobs (
	id VARCHAR(64) NOT NULL, state VARCHAR(16) NOT NULL, stage VARCHAR(64), progress FLOAT NOT NULL,
	envmap_id VARCHAR(64) NOT NULL, brdf_id VARCHAR(64) NOT NULL, brdf_spec JSON NOT NULL, params JSON NOT NULL,
	predicted JSON, measured JSON, failure_reason TEXT, retryable INTEGER NOT NULL, runs INTEGER NOT NULL,
	submissions INTEGER NOT NULL, worker VARCHAR(255), result_sha256 VARCHAR(64), created_at DATETIME NOT NULL,
	submitted_at DATETIME, started_at DATETIME, finished_at DATETIME, updated_at DATETIME NOT NULL,
	PRIMARY KEY (id)
);
CREATE INDEX ix_jobs_state ON jobs (state);
CREATE TABLE renders (
	"key" VARCHAR(64) NOT NULL, job_id VARCHAR(64) NOT NULL, view VARCHAR(128) NOT NULL, sha256 VARCHAR(64) NOT NULL,
	created_at DATETIME NOT NULL, PRIMARY KEY ("key")
);
"""

T0 = "2026-11-20 10:00:00.000000"
T1 = "2026-11-20 10:00:05.500000"
SHRM_DONE, SHRM_RUNNING = "a" * 64, "b" * 64
TRADEOFF_DONE, SCENE_QUEUED, TRADEOFF_FAILED = "c" * 64, "d" * 64, "e" * 64
ENV, BRDF, MANIFEST = "1" * 64, "2" * 64, "3" * 64
SPEC = {"kind": "phong", "s": 8.0}
PARAMS = {"epsilon": 0.01, "order": None, "p_order": None, "size": None}
POINTS = {"points": [{"method": "frequency", "measured_error": 0.012}], "meta": {"input": {"height": 16}}}
SCENE = {"scene": {"name": "s", "environment": ENV, "objects": []}, "preview_size": 0}


def schema_1_database(path: Path) -> None:
    con = sqlite3.connect(path)
    con.executescript(SCHEMA_1)
    jobs = [
        (SHRM_DONE, "succeeded", "done", 1.0, json.dumps({"seconds": 0.2}), json.dumps({"seconds": 0.3}), None, 0, 1, 1,
         "tcp://w1", MANIFEST, T0, T0, T0, T1, T1),
        (SHRM_RUNNING, "running", "prefiltering", 0.55, None, None, None, 0, 1, 1, "tcp://w2", None, T0, T0, T0, None,
         T0),
    ]
    con.executemany(
        "INSERT INTO jobs (id, state, stage, progress, envmap_id, brdf_id, brdf_spec, params, predicted, measured, "
        "failure_reason, retryable, runs, submissions, worker, result_sha256, created_at, submitted_at, started_at, "
        "finished_at, updated_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        [(r[0], r[1], r[2], r[3], ENV, BRDF, json.dumps(SPEC), json.dumps(PARAMS), *r[4:]) for r in jobs])
    tradeoff_request = {"envmap": ENV, "brdf_id": BRDF, "brdf": SPEC, "params": {"rows": 16}}
    con.executemany(
        "INSERT INTO analyses (id, kind, state, request, result, failure_reason, retryable, created_at, finished_at) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
        [(TRADEOFF_DONE, "tradeoff", "succeeded", json.dumps(tradeoff_request), json.dumps(POINTS), None, 0, T0, T1),
         (SCENE_QUEUED, "scene", "queued", json.dumps(SCENE), None, None, 0, T0, None),
         (TRADEOFF_FAILED, "tradeoff", "failed", json.dumps(tradeoff_request), None, "ValueError: x", 1, T0, T1)])
    con.execute("INSERT INTO renders VALUES (?, ?, ?, ?, ?)", ("k" * 64, SHRM_DONE, "0,0,1", "4" * 64, T1))
    con.commit()
    con.close()


def rows(db: Database) -> dict[str, Job]:
    with db.session() as s:
        return {r.id: r for r in s.query(Job).all()}


def utc(text: str) -> datetime:
    return datetime.strptime(text, "%Y-%m-%d %H:%M:%S.%f").replace(tzinfo=UTC)


def test_schema_1_rows_move_into_the_job_table(tmp_path: Path) -> None:
    path = tmp_path / "relight.db"
    schema_1_database(path)
    db = Database(f"sqlite:///{path}")
    assert db.create_all() == 5
    tables = set(inspect(db.engine).get_table_names())
    assert "analyses" not in tables and "jobs_v1" not in tables and {"jobs", "renders"} <= tables
    got = rows(db)
    assert set(got) == {SHRM_DONE, SHRM_RUNNING, TRADEOFF_DONE, SCENE_QUEUED, TRADEOFF_FAILED}

    done = got[SHRM_DONE]
    assert (done.kind, done.state, done.stage, done.progress) == ("shrm", "succeeded", "done", 1.0)
    assert done.request == {"envmap": ENV, "brdf": BRDF, "brdf_spec": SPEC, "params": PARAMS}
    assert done.predicted == {"seconds": 0.2} and done.measured == {"seconds": 0.3}
    assert done.result_sha256 == MANIFEST and done.worker == "tcp://w1" and (done.runs, done.submissions) == (1, 1)
    assert done.finished_at is not None and done.finished_at.replace(tzinfo=UTC) == utc(T1)
    running = got[SHRM_RUNNING]
    assert (running.kind, running.state, running.stage, running.progress) == ("shrm", "running", "prefiltering", 0.55)

    sweep = got[TRADEOFF_DONE]
    assert (sweep.kind, sweep.state, sweep.result) == ("tradeoff", "succeeded", POINTS)
    assert sweep.request["params"] == {"rows": 16} and sweep.created_at.replace(tzinfo=UTC) == utc(T0)
    scene = got[SCENE_QUEUED]
    assert (scene.kind, scene.state, scene.request, scene.result) == ("scene", "queued", SCENE, None)
    failed = got[TRADEOFF_FAILED]
    assert (failed.state, failed.failure_reason, failed.retryable) == ("failed", "ValueError: x", 1)

    with db.session() as s:  # the new table is complete: its index exists and inserts work
        s.add(Job(id="f" * 64, kind="scene", state="queued", request={}, retryable=0, runs=0, submissions=0))
    assert {i["name"] for i in inspect(db.engine).get_indexes("jobs")} >= {"ix_jobs_state", "ix_jobs_kind"}
    assert db.create_all() == 0 and len(rows(db)) == 6  # idempotent
    db.dispose()


def test_a_migration_interrupted_after_the_rename_completes_at_the_next_start(tmp_path: Path) -> None:
    """A process killed between renaming the old table and copying its rows loses nothing: the next start copies
    them."""
    path = tmp_path / "relight.db"
    schema_1_database(path)
    con = sqlite3.connect(path)
    con.executescript("ALTER TABLE jobs RENAME TO jobs_v1; DROP INDEX ix_jobs_state;")
    con.close()
    db = Database(f"sqlite:///{path}")
    assert db.create_all() == 5 and len(rows(db)) == 5
    db.dispose()


def test_an_unmigratable_database_names_the_problem(tmp_path: Path) -> None:
    path = tmp_path / "relight.db"
    schema_1_database(path)
    con = sqlite3.connect(path)
    con.executescript("CREATE TABLE jobs_v1 (id VARCHAR(64) PRIMARY KEY);")
    con.close()
    db = Database(f"sqlite:///{path}")
    with pytest.raises(RuntimeError, match="jobs_v1"):
        db.create_all()
    db.dispose()


@pytest.fixture(scope="module")
def pg_url() -> Iterator[str]:
    from .postgres import start_postgres

    db = start_postgres()
    yield db.url
    db.stop()


@pytest.mark.parametrize("dialect", ["sqlite", "postgresql"])
def test_a_schema_2_job_table_gains_the_claim_columns(dialect: str, tmp_path: Path,
                                                      request: pytest.FixtureRequest) -> None:
    """Schema 2's ``jobs`` had no ``owner`` / ``lease_until`` (the claim of one server among several): they are
    added at start-up, its rows kept, on SQLite and on PostgreSQL."""
    url = f"sqlite:///{tmp_path / 'relight.db'}" if dialect == "sqlite" else request.getfixturevalue("pg_url")
    old = Database(url)
    old.create_all()
    with old.engine.begin() as conn:  # schema 2 exactly: the table without the two columns, one row in it
        conn.execute(text("ALTER TABLE jobs DROP COLUMN owner"))
        conn.execute(text("ALTER TABLE jobs DROP COLUMN lease_until"))
        conn.execute(text("INSERT INTO jobs (id, kind, state, request, retryable, runs, submissions, progress, "
                          "created_at, updated_at) VALUES (:id, 'scene', 'queued', '{}', 0, 0, 0, 0.0, :t, :t)"),
                     {"id": SCENE_QUEUED, "t": utc(T0)})
    assert {"owner", "lease_until"}.isdisjoint(c["name"] for c in inspect(old.engine).get_columns("jobs"))
    old.dispose()

    db = Database(url)
    assert db.create_all() == 0
    assert {"owner", "lease_until"} <= {c["name"] for c in inspect(db.engine).get_columns("jobs")}
    with db.session() as s:
        row = s.get(Job, SCENE_QUEUED)
        assert row is not None and row.state == "queued" and row.owner is None and row.lease_until is None
        row.owner, row.lease_until = "host:1:abc", utc(T1)  # the columns take what the claim writes
    with db.session() as s:
        got = s.get(Job, SCENE_QUEUED)
        assert got is not None and got.owner == "host:1:abc"
        assert got.lease_until is not None
        lease = got.lease_until  # naive UTC from SQLite, aware from PostgreSQL
        assert (lease.replace(tzinfo=UTC) if lease.tzinfo is None else lease.astimezone(UTC)) == utc(T1)
    db.create_all()  # idempotent
    db.dispose()
