"""Result files of a prefiltering job, written into the blob store, and the manifest that describes them.

A result is three blobs:

* ``coefficients.exr`` — the layers as float32 RGB: a reflection map (one layer, plain ``R, G, B`` channels,
  exactly what ``relight prefilter`` writes) or an SHRM (one RGB layer ``c<k>.p<p>.q<q>`` per coefficient,
  ``relight.shrm_io``'s format, readable with ``relight.shrm_io.read_shrm``).
* ``coefficients.bin`` — the same layers as little-endian IEEE float16 for WebGL2: shape
  ``(layers, height, width, 3)``, C order, row 0 = the top row of the lat-long map (+Y,
  ``docs/conventions.md``). Upload it with ``texImage3D(TEXTURE_2D_ARRAY, 0, RGB16F, width, height, layers, 0,
  RGB, HALF_FLOAT, data)``. Values beyond the float16 range are clamped to +-65504 (never infinite); the count
  is in the manifest.
* ``manifest.json`` — this description (canonical JSON); its digest identifies the result.

A small ref ``job-<job id>`` names the manifest so that re-running a finished job (the server resubmits jobs
after a crash: at-least-once) finds the result instead of computing it again.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight.worker import faults
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore

MANIFEST_FORMAT: Final = "relight.shrm-result"
MANIFEST_VERSION: Final = 1
EXR_NAME: Final = "coefficients.exr"
#: Result EXRs are stored uncompressed: on prefiltered float32 maps ZIP saves ~7 % of the bytes at ~9x the
#: write time (measured: 320 x 640 x 3, 70 ms vs 7.6 ms), and every EXR reader (three.js included) handles it.
EXR_COMPRESSION: Final = "none"
BIN_NAME: Final = "coefficients.bin"


#: Report keys that differ between runs of the same job (not results): kept out of result files, so that a
#: recomputed result is byte-identical (timings go to the job's measurements instead).
VOLATILE_KEYS: Final = frozenset({"timings", "total_seconds", "cached"})


def strip_volatile(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: strip_volatile(v) for k, v in obj.items() if k not in VOLATILE_KEYS}
    if isinstance(obj, list | tuple):
        return [strip_volatile(v) for v in obj]
    return obj


def canonical_json(obj: Any) -> bytes:
    """Deterministic JSON bytes (sorted keys, no whitespace); NaN/Inf are refused."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


def job_ref(job_id: str) -> str:
    return f"job-{job_id}"


@dataclass(frozen=True)
class Layer:
    """One coefficient image: ``name`` is its EXR layer ("" for plain RGB channels), (p, q) its SHRM index."""

    name: str
    p: int
    q: int
    pixels: NDArray[np.floating]
    component: int = 0


def half_layers(layers: list[Layer]) -> tuple[bytes, int]:
    """The float16 texture bytes of ``layers`` (see the module docstring) and how many values were clamped."""
    from relight.envmap import to_half_safe

    stack = np.stack([np.asarray(layer.pixels, dtype=np.float32) for layer in layers])
    half, clamped = to_half_safe(stack)
    return np.ascontiguousarray(half).astype("<f2", copy=False).tobytes(), clamped


def layer_entries(layers: list[Layer]) -> list[dict[str, Any]]:
    """The manifest's ``layers`` list: index, EXR layer name, component and (p, q) of every texture layer."""
    return [{"index": i, "name": layer.name, "component": layer.component, "p": layer.p, "q": layer.q}
            for i, layer in enumerate(layers)]


def put_texture(store: BlobStore, layers: list[Layer]) -> dict[str, Any]:
    """Store the float16 texture of ``layers`` (``coefficients.bin``, module docstring); its manifest entry."""
    height, width = int(layers[0].pixels.shape[0]), int(layers[0].pixels.shape[1])
    bin_bytes, clamped = half_layers(layers)
    return {
        "sha256": store.put_bytes(bin_bytes),
        "bytes": len(bin_bytes),
        "media_type": "application/octet-stream",
        "dtype": "float16",
        "byte_order": "little",
        "shape": [len(layers), height, width, 3],
        "order": "layer, row (row 0 = top of the lat-long map, +Y), column, RGB",
        "clamped_values": clamped,
        "webgl": {
            "target": "TEXTURE_2D_ARRAY",
            "internalformat": "RGB16F",
            "format": "RGB",
            "type": "HALF_FLOAT",
            "width": width,
            "height": height,
            "depth": len(layers),
        },
    }


def write_result(
    store: BlobStore,
    job_id: str,
    layers: list[Layer],
    *,
    representation: str,
    description: dict[str, Any],
    exr_attributes: dict[str, str] | None = None,
) -> tuple[str, dict[str, Any]]:
    """Write the EXR, the float16 texture and the manifest; point the job's ref at the manifest.

    Returns ``(manifest digest, manifest)``.
    """
    from relight.envmap import write_exr, write_exr_layers

    if not layers:
        raise ValueError("a result needs at least one layer")
    height, width = int(layers[0].pixels.shape[0]), int(layers[0].pixels.shape[1])
    with store.new_file(".exr") as tmp:
        if len(layers) == 1 and layers[0].name == "":
            write_exr(tmp, np.asarray(layers[0].pixels, dtype=np.float32), compression=EXR_COMPRESSION,
                      attributes=exr_attributes)
        else:
            write_exr_layers(
                tmp,
                {layer.name: np.asarray(layer.pixels, dtype=np.float32) for layer in layers},
                compression=EXR_COMPRESSION,
                attributes=exr_attributes,
            )
        exr_size = tmp.stat().st_size
        exr_digest = store.put_file(tmp)
    manifest: dict[str, Any] = {
        "format": MANIFEST_FORMAT,
        "format_version": MANIFEST_VERSION,
        "id": job_id,
        "representation": representation,
        "height": height,
        "width": width,
        "layers": layer_entries(layers),
        "files": {
            EXR_NAME: {
                "sha256": exr_digest,
                "bytes": exr_size,
                "media_type": "image/x-exr",
                "dtype": "float32",
                "channels": ["R", "G", "B"] if layers[0].name == "" else [f"{lay.name}.{c}" for lay in layers
                                                                          for c in "RGB"],
            },
            BIN_NAME: put_texture(store, layers),
        },
        **description,
    }
    manifest_digest = store.put_bytes(canonical_json(manifest))
    faults.pause("blobs_written", job_id)  # TEST ONLY: off unless RELIGHT_TEST_FAULT_DIR is set
    store.set_ref(job_ref(job_id), manifest_digest)
    return manifest_digest, manifest


def load_manifest(store: BlobStore, digest: str) -> dict[str, Any]:
    """The manifest blob ``digest`` as a dict (verified)."""
    data: dict[str, Any] = json.loads(store.read(digest))
    return data


def existing_result(store: BlobStore, job_id: str) -> tuple[str, dict[str, Any]] | None:
    """The job's finished result if its manifest and every file it names are present and intact, else None.

    A corrupt file is removed by the verification (see :mod:`relight.worker.blobs`), so the job is computed again.
    """
    digest = store.get_ref(job_ref(job_id))
    if digest is None:
        return None
    try:
        manifest = load_manifest(store, digest)
        for info in manifest.get("files", {}).values():
            store.verified_path(info["sha256"])
    except (BlobMissing, BlobCorrupt, ValueError, KeyError, TypeError):
        store.delete_ref(job_ref(job_id))
        return None
    return digest, manifest
