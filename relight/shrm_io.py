"""SHRM files: one EXR with one RGB layer per coefficient map, plus a JSON manifest (seed 000 §4, §7.5).

Layout
------
* ``<name>.exr``: float32 (or half) RGB layers named ``c<k>.p<p>.q<q>`` — component k, term (p, q) of the real
  basis of ``relight.shrm`` (e.g. ``c0.p2.q-1``); every layer is an S x 2S lat-long map indexed by the component's
  centre direction (``docs/conventions.md``), holding the *local* SHRM coefficient ``Br_pq(alpha, beta)``.
* The manifest (JSON; format ``relight-shrm`` version 1): orders, resolution, layout, conventions, BRDF spec,
  per-component centre/structure/terms/predicted errors, timings and the relight version. It is stored both as
  the EXR string attribute ``relight.shrm`` and as the sidecar ``<name>.json`` next to the EXR.

:func:`write_shrm` / :func:`read_shrm` round-trip exactly: the maps as float32, the manifest as JSON.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__
from relight.envmap.exr import read_exr_layers, write_exr_layers
from relight.errors import InputError
from relight.reports import Report, ShrmComponentReport, ShrmReport, typed_or_plain
from relight.shrm import SHRM, Y00, SHRMComponent, terms_for

FORMAT = "relight-shrm"
FORMAT_VERSION = 1
ATTRIBUTE = "relight.shrm"

CONVENTIONS = {
    "directions": "lat-long, three.js equirectUv, +Y up; row i: theta = (i + 0.5) pi / S from +Y; column j: "
    "phi = -pi + (j + 0.5) 2 pi / W",
    "sh": "orthonormal complex Y_pq with Condon-Shortley phase; real basis Yr_p0 = Y_p0, Yr_{p,q>0} = sqrt2 (-1)^q "
    "Re Y_pq, Yr_{p,q<0} = sqrt2 (-1)^q Im Y_{p|q|} (relight.sh.to_real)",
    "local_frame": "R_{alpha,beta} = R_z(beta) R_y(alpha) in the SH frame (x', y', z') = (X, Z, Y): local x = "
    "theta-hat (cos a cos b, -sin a, cos a sin b), local y = phi-hat (-sin b, 0, cos b), local z = the centre C",
    "evaluation": "B(C, V) = sum_pq Br_pq(C) Yr_pq(theta_o, phi_o), (theta_o, phi_o) = angles of V in the local "
    "frame of C (seed 000 eq. 6); the global SHRM follows by eq. 8",
    "centres": "R = 2 (N.V) N - V; N; T = normalize(+Y x N) (+X at the poles)",
    "y00": repr(Y00),
}

_LAYER = re.compile(r"^c(\d+)\.p(\d+)\.q(-?\d+)$")


def layer_name(component: int, p: int, q: int) -> str:
    """``c<k>.p<p>.q<q>`` (module docstring)."""
    return f"c{component}.p{p}.q{q}"


def _jsonable(obj: Any) -> Any:
    """Plain-JSON copy: typed reports their JSON form (``relight.reports``), numpy scalars and arrays become Python
    numbers and lists, tuples lists."""
    if isinstance(obj, Report):
        return _jsonable(obj.to_json())
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def manifest(shrm: SHRM) -> dict[str, Any]:
    """The JSON manifest of an SHRM (module docstring)."""
    comps = []
    for k, c in enumerate(shrm.components):
        comps.append(
            {
                "index": k,
                "center": c.center,
                "structure": c.structure,
                "F": c.F,
                "P": c.P,
                "terms": [[p, q] for p, q in c.terms],
                "layers": [layer_name(k, p, q) for p, q in c.terms],
                "lobe": c.lobe,
                "report": c.report,
            }
        )
    rep = shrm.report
    out: dict[str, Any] = _jsonable(
        {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "relight_version": rep.get("relight_version", __version__),
            "layout": "local",
            "height": shrm.height,
            "width": shrm.width,
            "conventions": CONVENTIONS,
            "brdf": shrm.brdf,
            "components": comps,
            "orders": [{"F_B": c.F, "P_B": c.P, "center": c.center} for c in shrm.components],
            "predicted": rep.get("predicted"),
            "timings": rep.get("timings"),
            "report": {k: v for k, v in rep.items() if k != "components"},
        }
    )
    return out


def sidecar_path(path: str | os.PathLike[str]) -> Path:
    """``<name>.json`` beside ``<name>.exr``."""
    return Path(path).with_suffix(".json")


def write_shrm(path: str | os.PathLike[str], shrm: SHRM, *, half: bool = False) -> dict[str, Any]:
    """Write the SHRM EXR (float32, or half) and its sidecar manifest; returns the manifest."""
    if not shrm.components:
        raise InputError("an SHRM needs at least one component")
    layers: dict[str, NDArray[np.floating]] = {}
    for k, c in enumerate(shrm.components):
        if c.maps.shape[0] != len(c.terms) or c.maps.shape[-1] != 3:
            raise InputError(f"component {k}: maps of shape {c.maps.shape} do not match {len(c.terms)} RGB terms")
        for (p, q), m in zip(c.terms, c.maps, strict=True):
            layers[layer_name(k, p, q)] = np.asarray(m, dtype=np.float32)
    man = manifest(shrm)
    text = json.dumps(man, sort_keys=True)
    write_exr_layers(path, layers, half=half, attributes={ATTRIBUTE: text})
    sidecar_path(path).write_text(json.dumps(man, indent=2, sort_keys=True))
    return man


def _parse_manifest(text: str, where: str) -> dict[str, Any]:
    try:
        man = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: the SHRM manifest is not valid JSON ({exc.msg})") from None
    if not isinstance(man, dict) or man.get("format") != FORMAT:
        fmt = man.get("format") if isinstance(man, dict) else None
        raise InputError(f"{where}: not a relight SHRM manifest (format {fmt!r})")
    if man.get("format_version") != FORMAT_VERSION:
        raise InputError(f"{where}: unsupported SHRM format version {man.get('format_version')!r}")
    return man


def read_shrm(path: str | os.PathLike[str], *, max_pixels: int | None = None) -> SHRM:
    """Read an SHRM written by :func:`write_shrm` (manifest from the EXR attribute, else the sidecar)."""
    layers, attrs = read_exr_layers(os.fspath(path), max_pixels=max_pixels)
    if ATTRIBUTE in attrs:
        man = _parse_manifest(attrs[ATTRIBUTE], str(path))
    else:
        side = sidecar_path(path)
        if not side.exists():
            raise InputError(f"{path}: no SHRM manifest (no '{ATTRIBUTE}' attribute and no {side.name})")
        man = _parse_manifest(side.read_text(), str(side))
    for name in layers:
        if name and not _LAYER.match(name):
            raise InputError(f"{path}: unexpected layer {name!r} in an SHRM file")
    comps: list[SHRMComponent] = []
    try:
        for k, c in enumerate(man["components"]):
            terms = [(int(p), int(q)) for p, q in c["terms"]]
            structure = c["structure"]
            if structure not in ("radial", "azimuthal", "general"):
                raise InputError(f"{path}: component {k} has unknown structure {structure!r}")
            if terms != terms_for(structure, int(c["P"])):
                raise InputError(f"{path}: component {k} terms do not match structure {structure!r}, P={c['P']}")
            maps = []
            for p, q in terms:
                name = layer_name(k, p, q)
                if name not in layers:
                    raise InputError(f"{path}: layer {name!r} listed in the manifest is missing")
                maps.append(layers[name])
            arr = np.stack(maps).astype(np.float64)
            if arr.shape[1:3] != (int(man["height"]), int(man["width"])):
                raise InputError(f"{path}: layer size {arr.shape[1:3]} differs from the manifest's "
                                 f"{man['height']} x {man['width']}")
            comps.append(
                SHRMComponent(
                    center=str(c["center"]), structure=structure, F=int(c["F"]), P=int(c["P"]), terms=terms,
                    maps=arr, lobe=dict(c.get("lobe") or {}),
                    report=typed_or_plain(ShrmComponentReport, c.get("report") or {}),
                )
            )
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path}: malformed SHRM manifest ({exc!r})") from None
    if not comps:
        raise InputError(f"{path}: the SHRM manifest lists no components")
    report = typed_or_plain(ShrmReport, {**dict(man.get("report") or {}), "components": [c.report for c in comps]})
    return SHRM(components=comps, brdf=man.get("brdf"), report=report)
