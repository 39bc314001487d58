"""Interactive requests are not queued behind jobs (``relight.worker.slots``).

Every worker has one thread more than its job slots, and job tasks hold the Dask resource ``relight-job``. With
both workers of the embedded cluster busy with jobs that cannot end during the test (the TEST ONLY job delay of
10 minutes), an upload (decoded on a worker), the viewer's texture of the new map and a mesh upload must still be
answered, and the jobs must still be running when they are: before the split, the upload waited in Dask's queue for
a job to end (the read timeout of the stateful API fuzz run). The other seven of the nine jobs stay queued: job
slots, not threads, bound how many jobs run. Dask's scheduler-side queuing (``SCHEDULER_CONFIG``) is not reached
through HTTP here (a decode group only grows "root-ish" while its results are held); ``test_cluster_slots.py``
holds them on the server's own cluster and fails without the setting.
"""

from __future__ import annotations

from pathlib import Path

import httpx
import numpy as np
import pytest

from .postgres import Backend
from .routes.test_jobs_kinds import KINDS, submit
from .support import exr_bytes, make_envmap, start_server, wait_until

pytestmark = pytest.mark.timeout(300)

OBJ = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def test_uploads_and_textures_while_every_job_slot_is_busy(tmp_path_factory: pytest.TempPathFactory,
                                                            data_tmp: Path, database: Backend) -> None:
    server = start_server(tmp_path_factory.mktemp("slots"), {"RELIGHT_TEST_JOB_DELAY_S": "600"}, database=database)
    try:
        with httpx.Client(base_url=server.url, timeout=120) as http:
            env = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=501), data_tmp)).json()["id"]
            # more jobs than threads: the waiting ones sit on their workers, each holding no thread
            ids = [submit(http, kind, env, k) for k in (7, 8, 9) for kind in KINDS]
            assert len(ids) == 9

            def states() -> list[str]:
                return [http.get(f"/jobs/{i}").json()["state"] for i in ids]

            wait_until(lambda: states().count("running") == 2, 90, "two jobs to run (two workers, one slot each)")
            # every job slot is now held for 10 minutes: what follows runs on the interactive threads
            r = http.post("/envmaps", content=exr_bytes(make_envmap(48, seed=502), data_tmp))
            assert r.status_code in (200, 201), r.text
            new_env = r.json()["id"]
            t = http.get(f"/envmaps/{new_env}/texture.bin", params={"rows": 24})
            assert t.status_code == 200, t.text
            h, w, c = (int(v) for v in t.headers["X-Texture-Shape"].split(","))
            assert (h, c) == (24, 3)
            texels = np.frombuffer(t.content, "<f2")
            assert texels.size == h * w * c and np.isfinite(texels).all()
            m = http.post("/meshes", content=OBJ)
            assert m.status_code in (200, 201), m.text
            after = states()
            assert sorted(after) == ["queued"] * 7 + ["running"] * 2, after
            for i in ids:
                assert http.delete(f"/jobs/{i}").status_code in (200, 202, 204)
    finally:
        server.stop()
