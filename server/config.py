"""Service settings from ``RELIGHT_*`` environment variables (pydantic-settings), read once per process.

List settings (``RELIGHT_API_KEY_HASHES``, ``RELIGHT_CORS_ORIGINS``, ``RELIGHT_JOB_KIND_MODULES``) are
comma-separated.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Annotated

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

MiB = 1 << 20


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="RELIGHT_", extra="ignore")

    data_dir: Path = Field(Path("relight-data"), description="database and blobs live here by default")
    database_url: str | None = Field(None, description="any SQLAlchemy URL; default SQLite <data_dir>/relight.db")
    blob_dir: Path | None = Field(None, description="blob store root (shared with workers); default <data_dir>/blobs")

    scheduler: str | None = Field(None, description="tls://host:8786 (or tcp://) of an existing Dask scheduler; "
                                  "unset: embedded")
    tls_ca_file: Path | None = Field(None, description="scale-out: the cluster's CA certificate (relight.worker.tls)")
    tls_cert: Path | None = Field(None, description="scale-out: this server's certificate for the scheduler")
    tls_key: Path | None = Field(None, description="scale-out: its private key")
    n_workers: int = Field(2, ge=1, description="embedded cluster: worker processes")
    threads_per_worker: int = Field(1, ge=1, description="embedded cluster: jobs each worker runs at once (its "
                                    "job slots; one more thread serves interactive requests)")
    worker_memory_limit: str = Field("4GiB", description="embedded cluster: memory limit per worker process")

    max_upload_bytes: int = Field(256 * MiB, ge=1, description="largest file body (uploads)")
    max_json_bytes: int = Field(8 * MiB, ge=1, description="largest JSON body (a lobe1d table of 65536 RGB samples "
                                "is about 5 MiB)")
    max_pixels: int = Field(4096 * 2048, ge=1, description="largest environment map decoded whole (width x height); "
                            "jobs decode maps of at most this size")
    max_stream_pixels: int = Field(16384 * 8192, ge=1, description="largest lat-long EXR upload accepted above "
                                   "max_pixels: streamed in scanline chunks into its area-exact downsample to the "
                                   "largest lat-long map within max_pixels (issue 17, item 8), worker peak memory "
                                   "under relight.worker.tasks.stream_memory_bound")
    max_order: int = Field(1024, ge=0, description="largest order F a job may use")
    max_p_order: int = Field(16, ge=0, description="largest view order P a job may use")
    max_size: int = Field(2048, ge=2, description="largest output rows S")
    max_output_bytes: int = Field(2 << 30, ge=1, description="largest result a job may write (float32 RGB layers)")
    plan_workers: int = Field(2, ge=1, description="sandbox processes that plan requests (/plan, submissions)")
    plan_memory_bytes: int = Field(4 << 30, ge=256 << 20, description="address-space limit of each planning sandbox")
    plan_timeout_s: float = Field(300.0, gt=0, description="time limit of one plan (order search, coefficients)")
    plan_test_busy_s: float = Field(0.0, ge=0, le=600, description="test hook, 0 in production: every plan first "
                                    "computes for this many CPU seconds, so a test can catch plans in flight")
    min_free_bytes: int = Field(256 * MiB, ge=0, description="free disk below this in the blob store: /health "
                                "says degraded")
    health_interval_s: float = Field(1.0, gt=0, le=60, description="seconds between the background health probes "
                                     "(database, scheduler, disk) that /health answers from")
    gc_freeze: bool = Field(True, description="freeze the objects alive at start-up out of the garbage collector's "
                            "scans (relight.server.run.settle_heap); off only to measure what it buys "
                            "(bench/health.py)")
    max_active_jobs: int = Field(64, ge=1, description="queued + running jobs; more answer 429")
    decode_timeout_s: float = Field(120.0, gt=0, description="time limit for decoding one upload in a worker")
    blob_cache_bytes: int = Field(256 * MiB, ge=0, description="verified result bytes kept in memory for GETs")
    spectrum_lmax: int = Field(256, ge=0, description="bands of the lighting spectrum stored per map (for /plan)")

    api_key_hashes: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="SHA-256 hex digests of accepted API keys; empty: no authentication"
    )
    cors_origins: Annotated[list[str], NoDecode] = Field(default_factory=list)

    job_kind_modules: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="modules imported at start-up that register job kinds from outside this "
                                          "package (relight.server.services.kinds); the worker processes must be "
                                          "able to import their task functions too")

    preload_dir: Path | None = Field(None, description="environment maps ingested at start-up")
    preload_meshes: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="sample meshes ingested at start-up (bunny, teapot, bunny-100k)")
    max_mesh_bytes: int = Field(64 * MiB, ge=1, description="largest mesh file (also capped by max_upload_bytes)")
    max_mesh_vertices: int = Field(2_000_000, ge=3, description="most vertices a mesh file may declare")
    max_mesh_faces: int = Field(4_000_000, ge=1, description="most triangles a mesh file may declare")
    progress_interval_s: float = Field(0.25, ge=0, description="least seconds between stored progress updates")
    job_lease_s: float = Field(30.0, ge=1, description="a server's claim on a job it computes lasts this long unless "
                               "renewed (every quarter of it); another server on the same database takes over a "
                               "job whose claim has lapsed (its server died)")
    follow_interval_s: float = Field(0.5, gt=0, le=10, description="event streams of a job computed by another "
                                     "server read its row this often")
    log_level: str = "info"

    #: TEST ONLY: seconds each job waits (reporting progress) before computing, so tests can act "mid-job".
    test_job_delay_s: float = Field(0.0, ge=0, description="TEST ONLY: artificial delay per job")

    @field_validator("api_key_hashes", "cors_origins", "job_kind_modules", "preload_meshes", mode="before")
    @classmethod
    def _split(cls, v: object) -> object:
        if isinstance(v, str):
            return [s.strip() for s in v.split(",") if s.strip()]
        return v

    @field_validator("api_key_hashes")
    @classmethod
    def _hex(cls, v: list[str]) -> list[str]:
        out = []
        for h in v:
            h = h.lower().removeprefix("sha256:")
            if len(h) != 64 or any(c not in "0123456789abcdef" for c in h):
                raise ValueError(f"API key hashes must be SHA-256 hex digests, got {h[:12]!r}...")
            out.append(h)
        return out

    @property
    def resolved_blob_dir(self) -> Path:
        return (self.blob_dir or self.data_dir / "blobs").resolve()

    @property
    def resolved_database_url(self) -> str:
        return self.database_url or f"sqlite:///{(self.data_dir / 'relight.db').resolve()}"


@lru_cache
def get_settings() -> Settings:
    return Settings()  # fields come from the environment (pydantic-settings)
