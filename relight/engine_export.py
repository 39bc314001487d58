"""One engine export of one map as bytes (issue 17, items 1 and 2): what ``relight export``, ``relight bake`` and
the service's ``ibl`` job kind (``GET /envmaps/{id}/ibl``) all write, so that the three give identical files.

* :func:`chain_export` — the sun step (``relight.sun``), the target engine's prefiltered GGX cube chain
  (``relight.cube_chain``) as a KTX2 file (``relight.ktx2``) and its manifest (the per-level table with each
  level's App. B bound, the SH9 of the map after the sun step in every convention, the sun report, seconds).
  The KTX2 carries the manifest's deterministic part only (the level table without seconds, target, mapping, SH9,
  sun), so the same map and parameters give byte-identical files wherever they are computed.
* :func:`sh_export` — the sun step and the SH9 in every engine convention (``relight.sh9``), no chain.

:func:`without_seconds` drops the timing keys from a manifest: two manifests of the same export are equal after it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Export formats (``--format``; the service's ``format`` parameter takes all three).
FORMATS = ("ktx2", "sh", "gltf")
#: Targets (``relight.cube_chain.TARGET_MAPPING``'s keys, repeated so that argument parsers import nothing numerical;
#: tests/relight/test_engine_export.py checks they agree).
TARGETS = ("three", "filament", "gltf", "babylon")
#: Media type of KTX2 files (IANA registration, KTX 2.0 specification §A).
KTX2_MEDIA_TYPE = "image/ktx2"


@dataclass(frozen=True)
class ExportFiles:
    """``data``: the KTX2 file (chain) or the SH JSON document's UTF-8 bytes (sh); ``manifest``: the sidecar."""

    data: bytes
    manifest: dict[str, Any]


def chain_export(pixels: NDArray[np.floating], source: dict[str, Any], *, target: str, size: int,
                 levels: int | None, epsilon: float, sun_spec: str, pixel_format: str = "rgba16f",
                 extra: dict[str, Any] | None = None, brdf: str | None = None) -> ExportFiles:
    """The KTX2 chain of a lat-long map (H, W, 3) and its manifest (module docstring); ``pixel_format`` one of
    ``relight.ktx2.PIXEL_FORMATS`` (rgba16f, b10g11r11, e5b9g9r9); ``brdf`` a spec string whose lobe at view =
    normal each level holds instead of the target's split-sum GGX lobe (``relight.brdf.normal_view``)."""
    from relight.errors import InputError
    from relight.ktx2 import PIXEL_FORMATS

    if pixel_format not in PIXEL_FORMATS:
        raise InputError(f"unknown pixel format {pixel_format!r}; use one of {', '.join(PIXEL_FORMATS)}")
    from relight import __version__
    from relight.cube_chain import prefilter_chain
    from relight.ktx2 import write_ktx2
    from relight.sh9 import all_conventions
    from relight.sun import apply_sun

    sun = apply_sun(np.asarray(pixels, dtype=np.float64), sun_spec)
    chain = prefilter_chain(sun.pixels, target=target, size=size, levels=levels, epsilon=epsilon, brdf=brdf)
    table = chain.summary()
    manifest: dict[str, Any] = {
        "target": chain.target, "roughness_mapping": chain.mapping, "epsilon": chain.epsilon,
        "lighting_order": chain.lighting_order, "face_order": ["+X", "-X", "+Y", "-Y", "+Z", "-Z"],
        "source": source, "size": size, "levels": table, "seconds": chain.seconds, "relight_version": __version__,
        "sh9": all_conventions(sun.pixels), "sun": sun.report, **_brdf_key(chain), **(extra or {}),
    }
    if pixel_format != "rgba16f":  # absent for the default, so earlier manifests and files stay the same
        manifest["pixel_format"] = pixel_format
    data = write_ktx2([lv.faces for lv in chain.levels], _ktx2_meta(chain, manifest["sh9"], sun.report),
                      writer=f"relight {__version__}", vk_format=PIXEL_FORMATS[pixel_format])
    return ExportFiles(data, manifest)


def _brdf_key(chain: Any) -> dict[str, Any]:
    """``{"brdf": spec}`` for a ``--brdf`` chain, nothing for the default lobe (earlier files stay the same)."""
    return {} if chain.brdf is None else {"brdf": chain.brdf}


def _ktx2_meta(chain: Any, sh9: dict[str, Any], sun: dict[str, Any] | None) -> dict[str, Any]:
    """The KTX2's deterministic metadata: the level table without seconds, target, mapping, SH9, sun, brdf."""
    return {"levels": [{k: v for k, v in row.items() if k != "seconds"} for row in chain.summary()],
            "target": chain.target, "roughness_mapping": chain.mapping, "sh9": sh9, "sun": sun, **_brdf_key(chain)}


def gltf_export(pixels: NDArray[np.floating], source: dict[str, Any], *, size: int, levels: int | None,
                epsilon: float, sun_spec: str, into: bytes | None = None,
                extra: dict[str, Any] | None = None, brdf: str | None = None) -> ExportFiles:
    """The ``gltf`` target's chain, its SH9 and the sun as a GLB (``relight.gltf_ibl``), alone or added to ``into``."""
    from relight import __version__
    from relight.cube_chain import prefilter_chain
    from relight.gltf_ibl import gltf_lighting
    from relight.ktx2 import write_ktx2
    from relight.sh9 import all_conventions
    from relight.sun import apply_sun

    sun = apply_sun(np.asarray(pixels, dtype=np.float64), sun_spec)
    chain = prefilter_chain(sun.pixels, target="gltf", size=size, levels=levels, epsilon=epsilon, brdf=brdf)
    sh = all_conventions(sun.pixels)
    ktx2 = write_ktx2([lv.faces for lv in chain.levels], _ktx2_meta(chain, sh, sun.report),
                      writer=f"relight {__version__}")
    data, summary = gltf_lighting([lv.faces for lv in chain.levels], sh["gltf"]["coefficients"], sun.report,
                                  into=into, ktx2=ktx2, generator=f"relight {__version__}")
    manifest: dict[str, Any] = {
        "format": "gltf", "target": chain.target, "roughness_mapping": chain.mapping, "epsilon": chain.epsilon,
        "lighting_order": chain.lighting_order, "source": source, "size": size, "levels": chain.summary(),
        "seconds": chain.seconds, "relight_version": __version__, "sh9": sh, "sun": sun.report, "gltf": summary,
        **_brdf_key(chain), **(extra or {}),
    }
    return ExportFiles(data, manifest)


def sh_export(pixels: NDArray[np.floating], source: dict[str, Any], *, sun_spec: str,
              extra: dict[str, Any] | None = None) -> ExportFiles:
    """The map's SH9 after the sun step, in every convention, as a JSON document (also the manifest)."""
    import json

    from relight.sh9 import all_conventions
    from relight.sun import apply_sun

    sun = apply_sun(np.asarray(pixels, dtype=np.float64), sun_spec)
    doc = {"source": source, "sun": sun.report, "sh9": all_conventions(sun.pixels), **(extra or {})}
    return ExportFiles(json.dumps(doc, indent=2).encode("utf-8"), doc)


def without_seconds(obj: Any) -> Any:
    """``obj`` with every ``seconds`` key removed at every level (module docstring)."""
    if isinstance(obj, dict):
        return {k: without_seconds(v) for k, v in obj.items() if k != "seconds"}
    if isinstance(obj, list):
        return [without_seconds(v) for v in obj]
    return obj
