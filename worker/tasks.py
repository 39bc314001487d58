"""Entry points the server submits to Dask workers. Plain functions: arguments and results are plain data.

* :func:`analyze_envmap` decodes an uploaded environment map (untrusted bytes: only ever in a worker process,
  size-capped from the header first) and returns its metadata, SH power spectrum and a preview.
* :func:`compute_shrm` is the task of the ``shrm`` job kind (run by :func:`relight.worker.progress.run_job`): it
  dispatches on the BRDF (radially symmetric lobes go
  through ``relight.prefilter.prefilter_radial``; general BRDFs through the SHRM prefilter) and writes the
  result files (:mod:`relight.worker.results`).
* :func:`render_reflection` evaluates a result for one view direction (seed 000 eq. 12).

Inputs and outputs go through the shared blob store (:mod:`relight.worker.blobs`) whose root the server passes in.
"""

from __future__ import annotations

import json
import os
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError
from relight.jsonable import jsonable as _jsonable
from relight.planning.job import uses_reflection_map  # the dispatch rule lives with the planner
from relight.worker import faults
from relight.worker.blobs import BlobStore
from relight.worker.progress import JobContext, Reporter
from relight.worker.results import Layer, existing_result, load_manifest, strip_volatile, write_result
from relight.worker.specs import from_core, to_core

#: Rows of the PNG preview of an uploaded map.
PREVIEW_ROWS = 256


def warmup() -> dict[str, Any]:
    """Import the numerical core once per worker process so the first job does not pay for it."""
    import relight
    import relight.brdf.spec  # noqa: F401
    import relight.envmap  # noqa: F401
    import relight.prefilter  # noqa: F401

    return {"pid": os.getpid(), "algorithm_version": relight.ALGORITHM_VERSION}


# ----------------------------------------------------------------------------------------------------------------
# Environment maps


def stored_rows(height: int, max_pixels: int) -> int:
    """Rows of the stored downsample of a streamed lat-long upload: the largest lat-long map within
    ``max_pixels`` (what jobs may decode), at most the file's height and the core's ``STREAM_ROWS``."""
    from math import isqrt

    from relight.envmap.environment import STREAM_ROWS

    return max(1, min(height, STREAM_ROWS, isqrt(max_pixels // 2)))


def stream_memory_bound(width: int, rows: int, spectrum_lmax: int) -> int:
    """Bytes a streamed upload's analysis allocates above the worker's resident baseline, whatever the file's
    height: the streaming buffers (:func:`relight.envmap.stream.memory_bound`, default chunking) plus, for the
    ``rows x 2 rows`` stored map, :data:`STORED_COPIES` float64 RGB copies (the float32 map and its EXR write,
    the float64 statistics, the SH projection's input and ducc0's map) and the spectrum's coefficients."""
    from relight.envmap.stream import CHUNK_PIXELS, memory_bound

    chunk_rows = max(1, CHUNK_PIXELS // width)
    lmax = max(0, min(spectrum_lmax, rows - 1))
    return (memory_bound(width, rows, chunk_rows) + STORED_COPIES * rows * 2 * rows * 3 * 8
            + 4 * 3 * (lmax + 1) * (lmax + 2) // 2 * 16)


#: float64 RGB copies of the stored map the analysis holds at most (:func:`stream_memory_bound`).
STORED_COPIES = 8


def _decode_upload(store: BlobStore, digest: str, max_pixels: int,
                   max_stream_pixels: int | None) -> tuple[Any, int, int, str]:
    """(the map jobs will use, the file's width and height, the stored blob): a lat-long EXR above ``max_pixels``
    (and within ``max_stream_pixels``) is streamed from the stored file into its area-exact downsample to
    :func:`stored_rows` rows, stored as a float32 EXR and named by the map's ref (``BlobStore.stored_envmap``);
    anything else is decoded whole from the uploaded bytes."""
    from relight.envmap import probe, read_envmap, write_exr
    from relight.worker.blobs import stored_envmap_ref

    path = store.verified_path(digest)
    hdr = probe(path)
    if max_stream_pixels is None or hdr.format != "exr" or hdr.width != 2 * hdr.height or hdr.pixels <= max_pixels:
        env = read_envmap(store.read(digest), max_pixels=max_pixels)
        return env, hdr.width, hdr.height, digest
    env = read_envmap(path, max_pixels=max_stream_pixels, layout="latlong",
                      max_rows=stored_rows(hdr.height, max_pixels))
    with store.new_file(".exr") as tmp:
        write_exr(tmp, env.pixels)
        stored = store.put_file(tmp)
    store.set_ref(stored_envmap_ref(digest), stored)
    return env, hdr.width, hdr.height, stored


def analyze_envmap(
    store_root: str, digest: str, *, max_pixels: int, spectrum_lmax: int, preview_rows: int = PREVIEW_ROWS,
    max_stream_pixels: int | None = None,
) -> dict[str, Any]:
    """Decode the uploaded map ``digest`` and describe it.

    Returns format, size (the stored map's and the file's), layout, per-channel range and mean, the negative texels
    clamped, the luminance SH power spectrum ``E_l`` (l <= min(spectrum_lmax, H - 1)) with the total energy, and
    the digests of the stored map and of a PNG preview. A lat-long EXR above ``max_pixels`` is streamed
    (:func:`_decode_upload`, peak memory :func:`stream_memory_bound` above the worker's baseline).
    Raises ``relight.errors.InputError`` for anything the core rejects (non-finite pixels, bad size ...).
    """
    from relight.envmap import resample_latlong, write_png_preview
    from relight.prefilter import project_lighting

    reporter = Reporter(f"envmap-{digest}")
    reporter.started()
    store = BlobStore(store_root)
    env, source_width, source_height, stored = _decode_upload(store, digest, max_pixels, max_stream_pixels)
    px = env.pixels
    h, w = env.height, env.width
    lmax = max(0, min(spectrum_lmax, h - 1))
    lighting = project_lighting(px, lmax)
    spectrum = lighting.band_energy()
    preview = px if h <= preview_rows else resample_latlong(px, preview_rows)
    with store.new_file(".png") as tmp:
        write_png_preview(tmp, preview)
        preview_digest = store.put_file(tmp)
    flat = px.reshape(-1, 3).astype(np.float64)
    return {
        "format": env.source_format,
        "layout": env.layout,
        "width": w,
        "height": h,
        "source_width": source_width,
        "source_height": source_height,
        "stored_sha256": stored,
        "min": [float(v) for v in flat.min(axis=0)],
        "max": [float(v) for v in flat.max(axis=0)],
        "mean": [float(v) for v in flat.mean(axis=0)],
        "negatives_clamped": int(env.negatives_clamped),
        "min_negative": float(env.min_negative),
        "non_finite": 0,  # maps with NaN/Inf texels are rejected by read_envmap
        "spectrum_lmax": lmax,
        "sh_power_spectrum": [float(v) for v in spectrum],
        "total_energy": float(lighting.total_energy),
        "preview_sha256": preview_digest,
    }


# ----------------------------------------------------------------------------------------------------------------
# Jobs


def _radial(
    pixels: NDArray[np.float32], lobe: Any, params: dict[str, Any], report: Reporter
) -> tuple[list[Layer], str, dict[str, Any], dict[str, str]]:
    from relight.prefilter import prefilter_radial

    res = prefilter_radial(pixels, lobe, epsilon=params.get("epsilon"), order=params.get("order"),
                           size=params.get("size"))
    report("writing", 0.9)
    layers = [Layer(name="", p=0, q=0, pixels=res.map.astype(np.float32))]
    attributes = {"relight.report": json.dumps(_jsonable(strip_volatile(res.report.to_json())), sort_keys=True)}
    return layers, "reflection_map", res.report.to_json(), attributes


def _general(
    pixels: NDArray[np.float32], lobe: Any, params: dict[str, Any], report: Reporter
) -> tuple[list[Layer], str, dict[str, Any], dict[str, str]]:
    from relight.worker import shrm_adapter

    return shrm_adapter.prefilter(pixels, lobe, params, report)


def check_finite(layers: list[Layer]) -> None:
    """A result with NaN or Inf texels is a failure with its reason (an input at the edge of float64, such as a
    measured BRDF of 1e308 values, overflows while prefiltering), never a stored, "succeeded" result."""
    bad = {layer.name or "map": int(np.count_nonzero(~np.isfinite(layer.pixels))) for layer in layers}
    bad = {name: n for name, n in bad.items() if n}
    if bad:
        total = sum(bad.values())
        where = ", ".join(f"{name}: {n}" for name, n in list(bad.items())[:4])
        raise InputError(f"the result has {total} non-finite texels (NaN or Inf; {where}): the inputs overflow "
                         "float arithmetic; nothing was stored")


def compute_shrm(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    """The ``shrm`` job kind: run one prefiltering job and store its result (dispatches on the BRDF).

    ``request`` (canonical, :class:`relight.server.services.shrms.ShrmService`) holds ``envmap`` (input blob
    digest), ``brdf`` (its id), ``brdf_spec`` (canonical spec), ``params`` (``epsilon`` / ``order`` / ``p_order`` /
    ``size``) and optionally ``force`` (ignore an existing result). Runs through
    :func:`relight.worker.progress.run_job`. Returns the manifest digest and manifest, whether an existing result
    was reused, and timings.
    """
    from relight.brdf.spec import parse_brdf
    from relight.envmap import read_envmap

    t0 = time.perf_counter()
    job_id, store, report = ctx.job_id, ctx.store, ctx.report
    if not request.get("force"):
        found = existing_result(store, job_id)
        if found is not None:
            digest, manifest = found
            return {"manifest_sha256": digest, "manifest": manifest, "reused": True,
                    "task_seconds": time.perf_counter() - t0, "compute_seconds": 0.0}
    report("loading", 0.5)
    env = read_envmap(store.read(store.stored_envmap(request["envmap"])), max_pixels=ctx.max_pixels)
    lobe = parse_brdf(to_core(request["brdf_spec"], store))
    params: dict[str, Any] = request.get("params", {})
    pixels: Any = env.pixels  # float32 as read, float64 after the sun step
    sun_report = None
    if params.get("sun"):  # relight.sun: the map without its sun (or clamped); the manifest's input.sun says what
        from relight.sun import apply_sun

        sun = apply_sun(env.pixels, params["sun"])
        pixels, sun_report = sun.pixels, sun.report
    report("prefiltering", 0.55)
    t_compute = time.perf_counter()
    if uses_reflection_map(lobe, params):
        layers, representation, core_report, attributes = _radial(pixels, lobe, params, report)
    else:
        layers, representation, core_report, attributes = _general(pixels, lobe, params, report)
    compute_seconds = time.perf_counter() - t_compute
    faults.pause("compute", job_id, report.check_cancelled)  # TEST ONLY: off unless RELIGHT_TEST_FAULT_DIR is set
    report.check_cancelled()
    check_finite(layers)
    import relight

    description = {
        "envmap": request["envmap"],
        "brdf": request["brdf_spec"],
        "params": params,
        "algorithm_version": relight.ALGORITHM_VERSION,
        "relight_version": relight.__version__,
        "center": core_report.get("center"),
        "orders": core_report.get("orders"),
        "predicted": core_report.get("predicted"),
        "input": {"negatives_clamped": env.negatives_clamped, "min_negative": env.min_negative,
                  "height": env.height, "width": env.width, **({"sun": sun_report} if sun_report else {})},
    }
    attributes = {k: json.dumps(from_core(json.loads(v), store), sort_keys=True) for k, v in attributes.items()}
    digest, manifest = write_result(store, job_id, layers, representation=representation,
                                    description=from_core(_jsonable(strip_volatile(description)), store),
                                    exr_attributes=attributes)
    return {"manifest_sha256": digest, "manifest": manifest, "reused": False,
            "task_seconds": time.perf_counter() - t0, "compute_seconds": compute_seconds,
            "timings": _jsonable(core_report.get("timings"))}




# ----------------------------------------------------------------------------------------------------------------
# Views


def render_reflection(store_root: str, manifest_digest: str, view: list[float]) -> str:
    """Evaluate a result for the unit view direction ``view`` (seed 000 eq. 12); returns the EXR blob digest.

    The output is an S x 2S lat-long map indexed by the reflection vector R (``docs/conventions.md``).
    """
    from relight.envmap import write_exr

    store = BlobStore(store_root)
    manifest = load_manifest(store, manifest_digest)
    image = _reflection_image(store, manifest, np.asarray(view, dtype=np.float64))
    with store.new_file(".exr") as tmp:
        write_exr(tmp, image.astype(np.float32), attributes={"relight.view": ",".join(f"{v:.9g}" for v in view)})
        return store.put_file(tmp)


def _reflection_image(store: BlobStore, manifest: dict[str, Any], view: NDArray[np.float64]) -> NDArray[np.float64]:
    from relight.envmap import read_exr_layers
    from relight.worker import shrm_adapter

    digest = manifest["files"]["coefficients.exr"]["sha256"]
    if manifest["representation"] == "reflection_map":
        layers, _ = read_exr_layers(store.read(digest))
        orders = manifest.get("orders") or {}
        return shrm_adapter.reflect_radial(np.asarray(layers[""], dtype=np.float64), str(manifest.get("center")),
                                           int(orders.get("F_B", 0)), manifest.get("brdf") or {}, view)
    return shrm_adapter.reflect(str(store.verified_path(digest)), view)
