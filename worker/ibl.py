"""The ``ibl`` job kind's task: an engine-ready export of an uploaded map (issue 17; ``relight.engine_export``).

The request (``relight.contract.models.IblCreate``, canonicalised by ``relight.server.services.ibl``) names the map
and the export; the result is the export's manifest (``relight export``'s sidecar without its seconds: per-level
roughness, method, orders, predicted error and App. B bound, SH9 in every convention, the sun report), the seconds
per stage and level (``stage_seconds``: the job's ``measured`` record) and two files:
``chain.ktx2`` (format ``ktx2``: the KTX2 cube chain, byte-identical to ``relight export``'s for the same map and
parameters), ``lighting.glb`` (format ``gltf``: ``relight export --format gltf``'s GLB) or ``sh.json`` (format
``sh``: the SH9 document), plus ``manifest.json`` (the manifest: no timings, so that a job computed again writes
the same bytes). ``brdf`` (a spec string) is ``--brdf``.

The ``dfg`` kind's task, :func:`compute_dfg`, writes ``relight dfg``'s file (``relight.dfg.dfg_file``) as
``dfg.exr``, ``dfg.png`` or ``dfg.ktx2``.
"""

from __future__ import annotations

import json
import time
from typing import Any

from relight.worker.progress import JobContext

JSON = "application/json"
#: Media type of binary glTF (IANA registration, glTF 2.0 specification §4.4.4).
GLB = "model/gltf-binary"
#: Media types of the DFG table's formats.
DFG_MEDIA = {"exr": "image/x-exr", "png": "image/png", "ktx2": "image/ktx2"}


def compute_ibl(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.engine_export import KTX2_MEDIA_TYPE, chain_export, gltf_export, sh_export, without_seconds
    from relight.envmap import read_envmap

    t0 = time.perf_counter()
    ctx.report("loading", 0.05)
    env = read_envmap(ctx.store.read(ctx.store.stored_envmap(request["envmap"])), max_pixels=ctx.max_pixels)
    source = {"envmap": request["envmap"], "height": int(env.pixels.shape[0]), "width": int(env.pixels.shape[1])}
    ctx.report("prefiltering", 0.2)
    if request["format"] == "ktx2":
        files = chain_export(env.pixels, source, target=request["target"], size=int(request["size"]),
                             levels=request.get("levels"), epsilon=float(request["epsilon"]), sun_spec=request["sun"],
                             pixel_format=request.get("pixel_format", "rgba16f"), brdf=request.get("brdf"))
        name, media = "chain.ktx2", KTX2_MEDIA_TYPE
    elif request["format"] == "gltf":
        files = gltf_export(env.pixels, source, size=int(request["size"]), levels=request.get("levels"),
                            epsilon=float(request["epsilon"]), sun_spec=request["sun"], brdf=request.get("brdf"))
        name, media = "lighting.glb", GLB
    else:
        files = sh_export(env.pixels, source, sun_spec=request["sun"])
        name, media = "sh.json", JSON
    ctx.report.check_cancelled()
    manifest = without_seconds(files.manifest)  # the timings go to the job's measured record, not into a file
    stages = dict(files.manifest.get("seconds") or {})
    stages |= {f"level_{row['level']:02d}": row["seconds"] for row in files.manifest.get("levels") or []}
    manifest_bytes = json.dumps(manifest, indent=2).encode("utf-8")
    return {"manifest": manifest, "file": name, "task_seconds": time.perf_counter() - t0, "stage_seconds": stages,
            "files": {name: {"sha256": ctx.store.put_bytes(files.data), "media_type": media},
                      "manifest.json": {"sha256": ctx.store.put_bytes(manifest_bytes), "media_type": JSON}}}


def compute_dfg(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    """The split-sum DFG table as ``relight dfg`` writes it (module docstring)."""
    from relight.dfg import dfg_file

    t0 = time.perf_counter()
    ctx.report("integrating", 0.1)
    fmt = request["format"]
    data = dfg_file(int(request["size"]), multiscatter=bool(request["multiscatter"]), fmt=fmt)
    ctx.report.check_cancelled()
    name = f"dfg.{fmt}"
    return {"file": name, "size": int(request["size"]), "multiscatter": bool(request["multiscatter"]),
            "task_seconds": time.perf_counter() - t0,
            "files": {name: {"sha256": ctx.store.put_bytes(data), "media_type": DFG_MEDIA[fmt]}}}
