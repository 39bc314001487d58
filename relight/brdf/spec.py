"""BRDF specifications: strings, dicts and JSON files to lobes, and back (:func:`parse_brdf`, :func:`brdf_to_spec`).

String grammar (whitespace around tokens is ignored)::

    spec   := term ("+" term)*                       a sum of lobes (SumBRDF) when more than one term
    term   := kind [":" args]
    args   := key "=" value ("," key "=" value)*     numbers: 0.2, 1e-3; RGB: 0.9/0.8/0.7; words: fresnel=none
            | path                                   for merl, measured and lobe1d: merl:path/to/file.binary

e.g. ``lambert``, ``phong:s=32``, ``microfacet:sigma=0.2``, ``torrance-sparrow:alpha=0.2,fresnel=none``,
``ggx:alpha=0.3,fresnel=schlick,f0=0.04``, ``blinn-phong:s=64``, ``lafortune:preset=housepaint-blue``,
``ward:alpha=0.1,rho_s=0.05,rho_d=0.5``, ``oren-nayar:sigma=0.3``, ``kajiya-kay:s=32``,
``ggx-ld:roughness=0.3`` (the engines' split-sum prefilter lobe), ``gltf-pbr:base=0.9/0.6/0.2,metallic=1,roughness=0.4``
(glTF's metallic-roughness material, a preset for a Lambert + GGX sum; ``relight.brdf.gltf_pbr``),
``merl:gold.binary``, ``measured:table.npz``,
``lobe1d:lobe.json``, ``lambert:albedo=0.5+phong:s=64``,
``vmf:sigma=0.1`` (a normalised spherical Gaussian, sigma in radians), ``gaussian-lobes:fit.json`` (a fitted or
hand-written Gaussian-lobe material, ``relight.brdf.gaussian_lobes``).
Anisotropic forms (seed 003; ``relight.brdf.anisotropic``, tangent-frame BRDFs):
``torrance-sparrow:alpha_u=0.1,alpha_v=0.4,distribution=ggx,fresnel=none``,
``ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0``, ``ward:alpha_x=0.1,alpha_y=0.3,rho_d=0,rho_s=1``. Only
:func:`parse_frame_brdf` (which returns a :class:`~relight.brdf.frame.FrameBRDF`, every isotropic lobe adapted)
accepts them; :func:`parse_brdf` raises ``InputError`` for them (SHRMs cannot represent anisotropy).
A ``+`` inside a path is kept when what follows it does not start with a known kind.

A string ending in ``.json`` that does not start with ``kind:`` (or an ``os.PathLike``) is a JSON file holding a
dict or a list of dicts (a sum). Dicts: ``{"kind": "phong", "s": 32}``, ``{"kind": "sum", "lobes": [...]}``;
Lafortune lobes as ``{"kind": "lafortune", "diffuse": [..], "lobes": [[Cx, Cz, n], ...]}``; Lobe1D as
``{"kind": "lobe1d", "t": [..], "u": [..]}``, ``{"kind": "lobe1d", "table": [[t, u], ...]}`` (the canonical form)
or ``{"kind": "lobe1d", "path": "lobe.json"}`` (a JSON file with ``t`` and ``u`` or ``table``). Relative paths
inside a JSON file are resolved against that file's folder.

Every error is an ``InputError`` naming the offending kind, key or value and listing the valid ones.
:func:`brdf_to_spec` gives the canonical dict (keys sorted at every level, numbers as given) with
``parse_brdf(brdf_to_spec(x))`` equivalent to ``x``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from relight.brdf.anisotropic import AnisotropicTorranceSparrow, AshikhminShirley, WardAnisotropic, check_exclusive
from relight.brdf.base import Lobe
from relight.brdf.frame import FrameBRDF, FrameSum, as_frame_brdf
from relight.brdf.gaussian_lobes import GaussianLobes
from relight.brdf.gltf_pbr import gltf_pbr
from relight.brdf.measured import MERLBRDF, TabulatedBRDF
from relight.brdf.models import (
    GGX,
    BlinnPhong,
    KajiyaKay,
    Lafortune,
    Lambert,
    Lobe1D,
    Microfacet,
    OrenNayar,
    Phong,
    SumBRDF,
    TorranceSparrow,
    WardIsotropic,
)
from relight.brdf.splitsum import GGXSplitSum
from relight.brdf.vmf import VonMisesFisher
from relight.errors import InputError

Brdf = Lobe | SumBRDF

#: Value types of spec keys: "number", "color" (number or 3 numbers), "word", "path", "any" (dict-only structures).
_KEYS: dict[str, dict[str, str]] = {
    "lambert": {"albedo": "color"},
    "phong": {"s": "number"},
    "lobe1d": {"table": "any", "t": "any", "u": "any", "center": "word", "path": "path"},
    "microfacet": {"sigma": "number"},
    "torrance-sparrow": {
        "alpha": "number",
        "alpha_u": "number",
        "alpha_v": "number",
        "distribution": "word",
        "fresnel": "word",
        "f0": "color",
        "eta": "color",
        "k": "color",
    },
    "ggx": {"alpha": "number", "fresnel": "word", "f0": "color", "eta": "color", "k": "color"},
    "blinn-phong": {"s": "number"},
    "lafortune": {"preset": "word", "diffuse": "color", "lobes": "any"},
    "ward": {"rho_d": "color", "rho_s": "color", "alpha": "number", "alpha_x": "number", "alpha_y": "number"},
    "ashikhmin-shirley": {"nu": "number", "nv": "number", "rs": "color", "rd": "color"},
    "oren-nayar": {"sigma": "number", "albedo": "color"},
    "kajiya-kay": {"s": "number"},
    "ggx-ld": {"roughness": "number"},
    "gltf-pbr": {"base": "color", "metallic": "number", "roughness": "number"},
    "merl": {"path": "path", "lookup": "word"},
    "measured": {"path": "path"},
    "vmf": {"sigma": "number", "weight": "color"},
    "gaussian-lobes": {"elevations": "any", "fit": "any", "path": "path"},
}
#: Kinds whose string argument is a file path rather than key=value pairs.
_PATH_KINDS = ("merl", "measured", "lobe1d", "gaussian-lobes")
VALID_KINDS = sorted([*_KEYS, "sum"])


def _build(kind: str, kw: dict[str, Any]) -> Lobe | SumBRDF | FrameBRDF:
    if kind == "gltf-pbr":  # a preset: a sum of lobes
        try:
            return gltf_pbr(**kw)
        except TypeError as exc:
            raise InputError(f"{kind}: {exc}; valid keys are {sorted(_KEYS[kind])}") from None
    if kind == "torrance-sparrow":
        check_exclusive(kind, kw, "alpha", ("alpha_u", "alpha_v"))
    if kind == "ward":
        check_exclusive(kind, kw, "alpha", ("alpha_x", "alpha_y"))
    frame_makers: dict[str, Callable[..., FrameBRDF]] = {"ashikhmin-shirley": AshikhminShirley}
    if kind == "torrance-sparrow" and "alpha_u" in kw:
        frame_makers[kind] = AnisotropicTorranceSparrow
    if kind == "ward" and "alpha_x" in kw:
        frame_makers[kind] = WardAnisotropic
    if kind in frame_makers:
        try:
            return frame_makers[kind](**kw)
        except TypeError as exc:  # a required parameter is missing
            raise InputError(f"{kind}: {exc}; valid keys are {sorted(_KEYS[kind])}") from None
    makers: dict[str, Callable[..., Lobe]] = {
        "lambert": Lambert,
        "phong": Phong,
        "microfacet": Microfacet,
        "torrance-sparrow": TorranceSparrow,
        "ggx": GGX,
        "blinn-phong": BlinnPhong,
        "lafortune": Lafortune,
        "ward": WardIsotropic,
        "oren-nayar": OrenNayar,
        "kajiya-kay": KajiyaKay,
        "ggx-ld": GGXSplitSum,
        "merl": MERLBRDF,
        "vmf": VonMisesFisher,
    }
    if kind == "measured":
        if "path" not in kw:
            raise InputError("measured: needs a path to a .npz table")
        return TabulatedBRDF.load(kw["path"])
    if kind == "lobe1d":
        if "path" in kw:
            if set(kw) - {"path", "center"}:
                raise InputError("lobe1d: give either path or t/u, not both")
            table = _read_json(Path(kw["path"]), "lobe1d")
            if not isinstance(table, dict):
                raise InputError("lobe1d: the JSON file must hold an object {'t': [...], 'u': [...]} or {'table': ...}")
            if "center" in kw:
                table = {**table, "center": kw["center"]}
        else:
            table = kw
        return Lobe1D(table)
    if kind == "gaussian-lobes":
        if "path" in kw:
            if set(kw) != {"path"}:
                raise InputError("gaussian-lobes: give either path or elevations, not both")
            data = _read_json(Path(kw["path"]), "gaussian-lobes")
            if not isinstance(data, dict):
                raise InputError("gaussian-lobes: the JSON file must hold an object with 'elevations'")
            kw = {k: v for k, v in data.items() if k != "kind"}
        return GaussianLobes.from_spec(**kw)
    if kind == "merl" and "path" not in kw:
        raise InputError("merl: needs a path to a .binary file")
    try:
        return makers[kind](**kw)
    except TypeError as exc:  # a required parameter is missing
        raise InputError(f"{kind}: {exc}; valid keys are {sorted(_KEYS[kind])}") from None


def _read_json(path: Path, what: str) -> Any:
    if not path.is_file():
        raise InputError(f"{what}: no such file: {os.fspath(path)!r}")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{what}: {path.name} is not valid JSON ({exc})") from None


def _number(kind: str, key: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"{kind}: {key} must be a number, got {text!r}") from None
    if not math.isfinite(v):
        raise InputError(f"{kind}: {key} must be finite, got {text!r}")
    return v


def _parse_args(kind: str, args: str) -> dict[str, Any]:
    keys = _KEYS[kind]
    out: dict[str, Any] = {}
    for item in args.split(","):
        item = item.strip()
        if not item:
            raise InputError(f"{kind}: empty argument in {args!r}")
        if "=" not in item:
            raise InputError(f"{kind}: expected key=value, got {item!r}; valid keys are {sorted(keys)}")
        key, _, text = item.partition("=")
        key, text = key.strip(), text.strip()
        if key not in keys or keys[key] == "any":
            valid = sorted(k for k, t in keys.items() if t != "any")
            raise InputError(f"{kind}: unknown key {key!r}; valid keys are {valid}")
        if key in out:
            raise InputError(f"{kind}: key {key!r} given twice")
        typ = keys[key]
        if typ == "number":
            out[key] = _number(kind, key, text)
        elif typ == "color":
            parts = text.split("/")
            vals = [_number(kind, key, p.strip()) for p in parts]
            if len(vals) not in (1, 3):
                raise InputError(f"{kind}: {key} must be one number or 3 (r/g/b), got {text!r}")
            out[key] = vals[0] if len(vals) == 1 else vals
        else:
            out[key] = text
    return out


def _starts_term(text: str) -> bool:
    head = text.strip().split(":", 1)[0].strip().lower()
    return head in _KEYS


def _split_terms(spec: str) -> list[str]:
    pieces = spec.split("+")
    terms: list[str] = []
    for piece in pieces:
        if terms and not _starts_term(piece) and terms[-1].split(":", 1)[0].strip().lower() in _PATH_KINDS:
            terms[-1] += "+" + piece  # a '+' inside a file path
        else:
            terms.append(piece)
    return terms


def _parse_term(term: str) -> Lobe | SumBRDF | FrameBRDF:
    text = term.strip()
    if not text:
        raise InputError(f"empty BRDF term; valid kinds are {VALID_KINDS}")
    kind, sep, args = text.partition(":")
    kind = kind.strip().lower()
    if kind not in _KEYS:
        raise InputError(f"unknown BRDF kind {kind!r}; valid kinds are {VALID_KINDS}")
    if kind in _PATH_KINDS:
        path = args.strip()
        if not path:
            raise InputError(f"{kind}: needs a file path, e.g. '{kind}:file'")
        return _build(kind, {"path": path})
    kw = _parse_args(kind, args) if sep and args.strip() else {}
    if sep and not args.strip():
        raise InputError(f"{kind}: nothing after ':'; valid keys are {sorted(_KEYS[kind])}")
    return _build(kind, kw)


def spec_terms(spec: str) -> list[tuple[str, dict[str, Any]]]:
    """A spec string's terms as (kind, keyword arguments), unbuilt (a chain sets some per level,
    ``relight.brdf.normal_view``); path kinds give ``{"path": ...}``."""
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"empty BRDF spec; valid kinds are {VALID_KINDS}")
    out: list[tuple[str, dict[str, Any]]] = []
    for term in _split_terms(spec):
        kind, sep, args = term.strip().partition(":")
        kind = kind.strip().lower()
        if kind not in _KEYS:
            raise InputError(f"unknown BRDF kind {kind!r}; valid kinds are {VALID_KINDS}")
        if sep and not args.strip():
            raise InputError(f"{kind}: nothing after ':'")
        out.append((kind, {"path": args.strip()} if kind in _PATH_KINDS else
                    _parse_args(kind, args) if args.strip() else {}))
    return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _resolve(base: Path | None, value: Any) -> Any:
    if base is None or not isinstance(value, str):
        return value
    p = Path(value)
    return os.fspath(p if p.is_absolute() else base / p)


def _from_dict(d: Mapping[str, Any], base: Path | None) -> Brdf | FrameBRDF:
    if not isinstance(d, Mapping):
        raise InputError(f"a BRDF spec entry must be an object with a 'kind', got {type(d).__name__}")
    if "kind" not in d:
        raise InputError(f"a BRDF spec object needs a 'kind'; valid kinds are {VALID_KINDS}")
    kind = d["kind"]
    if not isinstance(kind, str) or kind.lower() not in [*_KEYS, "sum"]:
        raise InputError(f"unknown BRDF kind {kind!r}; valid kinds are {VALID_KINDS}")
    kind = kind.lower()
    rest = {k: v for k, v in d.items() if k != "kind"}
    if kind == "sum":
        if set(rest) != {"lobes"} or not isinstance(rest["lobes"], list):
            raise InputError(f"sum: needs exactly a 'lobes' list, got keys {sorted(rest)}")
        lobes = [_from_dict(x, base) for x in rest["lobes"]]
        if any(isinstance(lobe, FrameBRDF) for lobe in lobes):
            return _frame_sum(lobes)
        flat: list[Lobe] = []
        for lobe in lobes:
            if isinstance(lobe, SumBRDF):
                flat.extend(lobe.lobes)
            elif isinstance(lobe, Lobe):
                flat.append(lobe)
        return SumBRDF(flat)
    keys = _KEYS[kind]
    unknown = sorted(set(rest) - set(keys))
    if unknown:
        raise InputError(f"{kind}: unknown key {unknown[0]!r}; valid keys are {sorted(keys)}")
    for key, val in rest.items():
        typ = keys[key]
        if typ == "word" and not isinstance(val, str):
            raise InputError(f"{kind}: {key} must be a string, got {val!r}")
        if typ == "number" and not _is_number(val):
            raise InputError(f"{kind}: {key} must be a number, got {val!r}")
        if typ == "color" and not (_is_number(val) or (isinstance(val, list) and all(_is_number(x) for x in val))):
            raise InputError(f"{kind}: {key} must be a number or a list of 3 numbers (RGB), got {val!r}")
        if typ == "path":
            if not isinstance(val, (str, os.PathLike)):
                raise InputError(f"{kind}: {key} must be a file path, got {val!r}")
            rest[key] = _resolve(base, os.fspath(val))
    return _build(kind, rest)


def _isotropic_only(obj: Brdf | FrameBRDF) -> Brdf:
    if isinstance(obj, FrameBRDF):
        raise InputError(
            f"{obj.kind}: this BRDF is anisotropic (it needs a tangent frame); SHRMs cannot represent it, only the "
            "SH-table path (relight.brdf.spec.parse_frame_brdf, `relight sh-table`) accepts it"
        )
    return obj


def _frame_sum(terms: list[Any]) -> FrameBRDF:
    flat: list[FrameBRDF] = []
    for term in terms:
        f = as_frame_brdf(term)
        flat.extend(f.terms if isinstance(f, FrameSum) else [f])
    return flat[0] if len(flat) == 1 else FrameSum(flat)


def parse_frame_brdf(spec: str | Mapping[str, Any] | list[Any] | os.PathLike[str]) -> FrameBRDF:
    """Any BRDF spec (isotropic, anisotropic or measured) as a :class:`~relight.brdf.frame.FrameBRDF`: the forms of
    :func:`parse_brdf` plus the anisotropic ones (module docstring); isotropic lobes come adapted
    (:class:`~relight.brdf.frame.LobeAdapter`) and sums as :class:`~relight.brdf.frame.FrameSum`."""
    return _frame_sum([_parse_any(spec)])


def parse_brdf(spec: str | Mapping[str, Any] | list[Any] | os.PathLike[str]) -> Brdf:
    """A lobe or a :class:`SumBRDF` from a spec string, a dict / list of dicts, or a JSON file (module docstring)."""
    return _isotropic_only(_parse_any(spec))


def _parse_any(spec: str | Mapping[str, Any] | list[Any] | os.PathLike[str]) -> Brdf | FrameBRDF:
    path: Path | None = None
    if isinstance(spec, os.PathLike):
        path = Path(spec)
    elif isinstance(spec, str) and spec.strip().lower().endswith(".json") and not _starts_term(spec):
        path = Path(spec.strip())
    if path is not None:
        return _data_any(_read_json(path, "brdf spec"), path.parent)
    if isinstance(spec, (Mapping, list)):
        return _data_any(spec, None)
    if not isinstance(spec, str):
        raise InputError(f"a BRDF spec must be a string, a dict or a JSON file path, got {type(spec).__name__}")
    if not spec.strip():
        raise InputError(f"empty BRDF spec; valid kinds are {VALID_KINDS}")
    terms: list[Lobe | FrameBRDF] = []
    for t in _split_terms(spec):
        parsed = _parse_term(t)
        terms.extend(parsed.lobes if isinstance(parsed, SumBRDF) else [parsed])  # presets expand to their lobes
    lobes = [t for t in terms if isinstance(t, Lobe)]
    if len(lobes) < len(terms):
        return _frame_sum(terms)
    return lobes[0] if len(lobes) == 1 else SumBRDF(lobes)


def parse_brdf_data(data: Any, base: Path | None = None) -> Brdf:
    """Dict or list-of-dicts form of :func:`parse_brdf`; relative paths resolve against ``base``."""
    return _isotropic_only(_data_any(data, base))


def _data_any(data: Any, base: Path | None) -> Brdf | FrameBRDF:
    if isinstance(data, list):
        return _from_dict({"kind": "sum", "lobes": data}, base)
    if isinstance(data, Mapping):
        return _from_dict(data, base)
    raise InputError(f"a BRDF spec must be an object or a list of objects, got {type(data).__name__}")


def _sorted(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {k: _sorted(obj[k]) for k in sorted(obj)}
    if isinstance(obj, (list, tuple)):
        return [_sorted(x) for x in obj]
    return obj


def brdf_to_spec(obj: Brdf | FrameBRDF) -> dict[str, Any]:
    """Canonical dict of a lobe or sum: ``{"kind": ..., **params}`` with keys sorted at every level.

    ``parse_brdf(brdf_to_spec(x))`` rebuilds an equivalent object. Raises ``InputError`` for objects that cannot
    be serialised (a :class:`Lobe1D` given as a callable, an unsaved :class:`TabulatedBRDF`).
    """
    if not isinstance(obj, (Lobe, SumBRDF, FrameBRDF)):
        raise InputError(f"not a BRDF: {type(obj).__name__}")
    return dict(_sorted(obj.spec()))
