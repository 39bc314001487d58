"""``/shrms``: end to end against the library, identical submissions, caching headers, corrupt results."""

from __future__ import annotations

import hashlib
import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
import pytest

from relight.client.sdk import RelightClient
from relight.contract.models import JobPublic, JobState

from ..support import Server, assert_healthy, assert_problem, exr_bytes, library_map, make_envmap, read_exr

pytestmark = pytest.mark.timeout(180)


def metric(text: str, name: str) -> float:
    for line in text.splitlines():
        if line.startswith(name + " ") or line.startswith(name + "{"):
            return float(line.rsplit(" ", 1)[1])
    raise AssertionError(f"metric {name} not found")


def test_upload_plan_submit_events_result_bit_exact(client: RelightClient, sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr, name="sky.exr")
    plan = client.plan(env.id, "phong:s=32", epsilon=0.01)
    assert plan.representation == "reflection_map" and not plan.cached
    assert plan.orders.F_B >= 1 and plan.predicted_seconds > 0
    job = client.submit(env.id, "phong:s=32", epsilon=0.01)
    assert job.id == plan.job_id
    assert job.predicted is not None and job.predicted.orders == plan.orders

    updates = list(client.events(job.id, timeout=60))
    assert updates[-1].state == JobState.succeeded, updates[-1]
    progress = [u.progress for u in updates]
    assert progress == sorted(progress), f"progress went backwards: {progress}"

    done = client.get_job(job.id)
    assert done.state == JobState.succeeded and done.runs == 1 and done.measured is not None
    assert done.measured.orders is not None and done.measured.orders.F_B == plan.orders.F_B

    expected = library_map(sample_exr, "phong:s=32", epsilon=0.01)
    got = read_exr(client.download(job.id, "coefficients.exr"))[""]
    assert got.dtype == np.float32 and got.shape == expected.shape
    assert np.array_equal(got.view(np.uint32), expected.view(np.uint32)), "EXR differs from the library bit for bit"

    from relight.envmap import to_half_safe

    half, _ = to_half_safe(expected)
    assert client.download(job.id, "coefficients.bin") == half.astype("<f2").tobytes()
    manifest = client.get_shrm(job.id)
    assert manifest.files["coefficients.bin"]["shape"] == [1, *expected.shape]


def test_identical_concurrent_submissions_share_one_job(server: Server, data_tmp: Path) -> None:
    exr = exr_bytes(make_envmap(32, seed=7), data_tmp)
    with server.client() as c:
        env = c.upload_envmap(exr)
        runs_before = metric(httpx.get(server.url + "/metrics").text, "relight_job_runs_total")
        created_before = metric(httpx.get(server.url + "/metrics").text, "relight_jobs_created_total")
    body = {"envmap": env.id, "brdf": {"kind": "phong", "s": 16}, "epsilon": 0.02}

    def post(_: int) -> httpx.Response:
        return httpx.post(server.url + "/shrms", json=body, timeout=60)

    with ThreadPoolExecutor(20) as pool:
        answers = list(pool.map(post, range(20)))
    assert {r.status_code for r in answers} <= {200, 202}, [r.text for r in answers if r.status_code >= 300]
    ids = {r.json()["id"] for r in answers}
    assert len(ids) == 1
    job_id = ids.pop()
    with server.client() as c:
        final = c.wait(job_id, timeout=60)
        assert final.submissions == 1 and final.runs == 1
        text = httpx.get(server.url + "/metrics").text
        assert metric(text, "relight_job_runs_total") - runs_before == 1
        assert metric(text, "relight_jobs_created_total") - created_before == 1
        again = httpx.post(server.url + "/shrms", json=body, timeout=60)
        assert again.status_code == 200
        assert JobPublic.model_validate(again.json()).cached
        assert again.headers["content-location"] == f"/shrms/{job_id}"


def test_strong_etags_and_304(client: RelightClient, http: httpx.Client, sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    job = client.wait(client.submit(env.id, "phong:s=32", epsilon=0.01).id, timeout=60)
    for path in (f"/shrms/{job.id}", f"/shrms/{job.id}/coefficients.exr", f"/shrms/{job.id}/coefficients.bin",
                 f"/envmaps/{env.id}/preview.png"):
        r = http.get(path)
        assert r.status_code == 200, r.text
        etag = r.headers["etag"]
        assert etag == '"' + hashlib.sha256(r.content).hexdigest() + '"', path
        assert "immutable" in r.headers["cache-control"]
        r2 = http.get(path, headers={"If-None-Match": etag})
        assert r2.status_code == 304 and r2.content == b""
        assert http.get(path, headers={"If-None-Match": '"0000"'}).status_code == 200
    manifest = json.loads(http.get(f"/shrms/{job.id}").content)
    assert manifest["files"]["coefficients.exr"]["sha256"] == http.get(
        f"/shrms/{job.id}/coefficients.exr").headers["etag"].strip('"')


def test_reflection_view(client: RelightClient, http: httpx.Client, sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    job = client.wait(client.submit(env.id, "phong:s=32", epsilon=0.01).id, timeout=60)
    img = read_exr(client.reflection(job.id, (0.0, 0.0, 2.0)))[""]
    # a Phong lobe is centred on R: the view-dependent map is the reflection map itself (eq. 12 with P = 0)
    assert np.array_equal(img, read_exr(client.download(job.id))[""])
    assert_problem(http.get(f"/shrms/{job.id}/reflection.exr", params={"view": "0,0,0"}), 422, "non-zero")
    assert_problem(http.get(f"/shrms/{job.id}/reflection.exr", params={"view": "1,nan,0"}), 422, "finite")
    assert_problem(http.get(f"/shrms/{job.id}/reflection.exr", params={"view": "up"}), 422, "'up'")


def test_corrupt_result_is_recomputed_not_served(server: Server, data_tmp: Path) -> None:
    exr = exr_bytes(make_envmap(32, seed=11), data_tmp)
    with server.client() as c, httpx.Client(base_url=server.url, timeout=60) as http:
        env = c.upload_envmap(exr)
        job = c.wait(c.submit(env.id, "phong:s=8", epsilon=0.05).id, timeout=60)
        good = c.download(job.id)
        digest = c.get_shrm(job.id).files["coefficients.exr"]["sha256"]
        blob = next(Path(server.args[server.args.index("--data") + 1]).rglob(digest))
        blob.chmod(0o644)
        raw = bytearray(blob.read_bytes())
        raw[len(raw) // 2] ^= 0xFF
        blob.write_bytes(bytes(raw))

        r = http.get(f"/shrms/{job.id}/coefficients.exr")
        assert_problem(r, 503, "corrupt")
        assert r.headers.get("retry-after")
        again = c.wait(job.id, timeout=60)
        assert again.state == JobState.succeeded
        assert c.download(job.id) == good
        assert_healthy(http)


def test_shrm_end_to_end_bit_exact(client: RelightClient, http: httpx.Client, data_tmp: Path) -> None:
    """A view-dependent BRDF goes through the SHRM path; the layers equal ``create_shrm`` bit for bit and the
    file reads back with ``relight.shrm_io.read_shrm``."""
    from relight.brdf.spec import parse_brdf
    from relight.envmap import read_envmap
    from relight.shrm import create_shrm, reflect
    from relight.shrm_io import layer_name, read_shrm

    exr = exr_bytes(make_envmap(32, seed=41), data_tmp)
    env = client.upload_envmap(exr)
    spec = {"kind": "microfacet", "sigma": 0.35}
    plan = client.plan(env.id, spec, order=6, p_order=2, size=24)
    assert plan.representation == "shrm" and plan.orders.P_B == 2 and plan.output.layers == 9
    job = client.wait(client.submit(env.id, spec, order=6, p_order=2, size=24).id, timeout=120)
    manifest = client.get_shrm(job.id)
    assert manifest.representation == "shrm" and len(manifest.layers) == 9

    expected = create_shrm(read_envmap(exr).pixels, parse_brdf(spec), order=6, p_order=2, size=24)
    data = client.download(job.id)
    layers = read_exr(data)
    comp = expected.components[0]
    for (p, q), m in zip(comp.terms, comp.maps, strict=True):
        want = m.astype(np.float32)
        got = layers[layer_name(0, p, q)]
        assert np.array_equal(got.view(np.uint32), want.view(np.uint32)), (p, q)

    path = data_tmp / "shrm.exr"
    path.write_bytes(data)
    back = read_shrm(path)
    view = (0.3, 0.4, 0.866)
    got_view = read_exr(client.reflection(job.id, view))[""]
    want_view = reflect(back, np.array(view) / np.linalg.norm(view)).astype(np.float32)
    np.testing.assert_allclose(got_view, want_view, rtol=1e-6, atol=1e-7)
    r = http.get(f"/shrms/{job.id}/coefficients.bin")
    assert len(r.content) == 9 * 24 * 48 * 3 * 2


def test_async_client(server: Server, data_tmp: Path) -> None:
    """``AsyncRelightClient`` does the same round trip (upload from a file, submit, events, download)."""
    import asyncio
    import concurrent.futures

    from relight.client import AsyncRelightClient
    from relight.client.errors import ApiError

    src = data_tmp / "async.exr"
    src.write_bytes(exr_bytes(make_envmap(32, seed=51), data_tmp))

    async def run() -> tuple[JobPublic, bytes, int]:
        async with AsyncRelightClient(server.url) as c:
            env = await c.upload_envmap(src)
            job = await c.submit(env.id, "lambert", epsilon=0.01)
            done = await c.wait(job.id, timeout=60)
            try:
                await c.get_job("0" * 64)
            except ApiError as exc:
                assert exc.status == 404 and "0" * 64 in (exc.detail or "")
            manifest = await c.get_shrm(done.id)
            shape = manifest.files["coefficients.bin"]["shape"]
            return done, await c.download(done.id, "coefficients.bin"), 2 * int(np.prod(shape))

    # a thread of its own: asyncio.run refuses to start where a loop runs (Playwright's sync API keeps one in the
    # main thread once a browser test of the same session has started it)
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        done, data, size = pool.submit(asyncio.run, run()).result()
    assert done.state == JobState.succeeded
    assert done.predicted is not None and done.predicted.representation == "reflection_map"
    assert len(data) == size  # float16 layers, as the manifest describes them


def test_float16_texture_clamps_instead_of_overflowing(client: RelightClient, data_tmp: Path) -> None:
    img = make_envmap(32, seed=61)
    img[4:6, 10:12] = 5.0e6  # a sun far brighter than float16 can hold after filtering
    env = client.upload_envmap(exr_bytes(img, data_tmp))
    job = client.wait(client.submit(env.id, "phong:s=64", order=20, size=32).id, timeout=60)
    exr = read_exr(client.download(job.id))[""]
    assert exr.max() > 65504.0
    half = np.frombuffer(client.download(job.id, "coefficients.bin"), dtype="<f2")
    assert np.isfinite(half).all() and float(half.max()) == 65504.0
    assert client.get_shrm(job.id).files["coefficients.bin"]["clamped_values"] == int(np.sum(np.abs(exr) > 65504.0))
