"""A throw-away PostgreSQL server for the service tests: Debian's ``postgresql`` package (installed by ``make test``
through the Makefile's SYSTEM_PKGS), ``initdb`` into a temporary directory, ``pg_ctl start`` on a free loopback
port with trust authentication, one database ``relight``. As root (CI), the server runs as the ``postgres`` user
(PostgreSQL refuses to run as root). ``fsync=off``: a test database needs no durability.
"""

from __future__ import annotations

import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import psycopg


def _bin_dir() -> Path:
    found = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"))
    if not found:
        raise AssertionError("PostgreSQL is not installed: make test installs Debian's postgresql (SYSTEM_PKGS)")
    return found[-1].parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Postgres:
    root: Path
    port: int
    prefix: list[str]
    bin_dir: Path

    @property
    def url(self) -> str:
        """The SQLAlchemy URL of the ``relight`` database (psycopg 3)."""
        return f"postgresql+psycopg://relight@127.0.0.1:{self.port}/relight"

    def _ctl(self, *args: str) -> None:
        subprocess.run([*self.prefix, str(self.bin_dir / "pg_ctl"), "-D", str(self.root / "data"), *args],
                       check=True, capture_output=True, timeout=120)

    def stop(self) -> None:
        self._ctl("-m", "immediate", "stop")
        shutil.rmtree(self.root, ignore_errors=True)

    def new_database(self, name: str) -> str:
        """Create the database ``name``; its SQLAlchemy URL."""
        with psycopg.connect(f"postgresql://relight@127.0.0.1:{self.port}/postgres", autocommit=True) as c:
            c.execute(f'CREATE DATABASE "{name}"')
        return f"postgresql+psycopg://relight@127.0.0.1:{self.port}/{name}"

    def count(self, sql: str) -> int:
        with psycopg.connect(f"postgresql://relight@127.0.0.1:{self.port}/relight") as c:
            row = c.execute(sql).fetchone()
        return int(row[0]) if row else 0


def start_postgres() -> Postgres:
    """Its own directory under the system's temporary folder (pytest's are private to root, and the server runs as
    ``postgres``); removed by :meth:`Postgres.stop`."""
    bin_dir = _bin_dir()
    root = Path(tempfile.mkdtemp(prefix="relight-pg-"))
    prefix: list[str] = []
    if os.geteuid() == 0:
        pw = pwd.getpwnam("postgres")
        os.chown(root, pw.pw_uid, pw.pw_gid)
        prefix = ["runuser", "-u", "postgres", "--"]
    subprocess.run([*prefix, str(bin_dir / "initdb"), "-D", str(root / "data"), "-U", "relight", "-A", "trust",
                    "--no-sync", "-E", "UTF8"], check=True, capture_output=True, timeout=120)
    pg = Postgres(root, _free_port(), prefix, bin_dir)
    pg._ctl("-l", str(root / "log"), "-w", "-o",
            f"-p {pg.port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off", "start")
    with psycopg.connect(f"postgresql://relight@127.0.0.1:{pg.port}/postgres", autocommit=True) as c:
        c.execute("CREATE DATABASE relight")
    return pg


@dataclass
class Backend:
    """The database of the service tests' servers: ``sqlite`` (the server's default, a file in its data directory)
    or ``postgresql``: one database per data directory on one PostgreSQL server, so a server restarted on its data
    directory finds its database again, as with SQLite (:func:`tests.service.support.start_server`)."""

    name: str
    pg: Postgres | None = None
    _urls: dict[Path, str] = field(default_factory=dict)

    def env_for(self, data_dir: Path) -> dict[str, str]:
        if self.pg is None:
            return {}
        key = data_dir.resolve()
        if key not in self._urls:
            self._urls[key] = self.pg.new_database(f"relight_{len(self._urls)}")
        return {"RELIGHT_DATABASE_URL": self._urls[key]}
