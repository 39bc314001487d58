"""Scene planner: simulate only what the scene calls for (seed 000 §3.1, §4 eqs. 6–8, §5.1, §5.2, §7, App. C).

A *scene* (:class:`Scene`, read from JSON by :func:`scene_from_dict` with strict validation) holds an environment,
objects (a sphere or a mesh name, a bounding radius ``size`` and the ``distance`` from the viewer to its centre, the
direction ``view`` from the object toward the viewer, and a material: a BRDF spec, possibly a sum of lobes) and
either a global tolerance ``epsilon`` (the paper's uncaptured energy fraction, §5.1) or a time budget in seconds.

:func:`plan_scene` decides, per lobe of every material:

* **Lambertian** lobe -> irradiance coefficients only: the order from the tolerance is F = 2 (9 coefficients,
  seed 000 §5.2 footnote 1) whenever ``epsilon >= 1/128``, the clamped cosine's energy beyond l = 2; a stricter
  tolerance raises F (4, 6, ...) and the plan says so;
* other **radially symmetric** lobe (Phong, tabulated 1-D lobes) -> a 2-D reflection map (P = 0, §3.1);
* lobe **without azimuthal dependence** (Kajiya–Kay) -> q = 0 terms only, P + 1 maps (§7.1, §7.3);
* **general** isotropic lobe -> the full ``(P + 1)^2``-map SHRM (§4);
* a **sum of lobes**: each lobe at its own orders (F_rho, P_rho) from the tolerance (``spectrum_for_tolerance`` /
  App. C's order search), ``F_B = min(F_rho, F_L, H - 1)`` (minimum-of-orders rule, §5.1);
* the lighting is projected **once**, to the largest order any lobe needs, and shared (App. C: ``O(F_B S_L^2)``);
  identical lobes at identical orders and resolution are computed once and shared between objects;
* **distant vs near viewer**. The viewer at distance d sees an object of bounding radius r under the view
  directions of a cone of full angle ``delta = 2 asin(r / d)``. A global SHRM (eq. 7) uses one V for the whole
  object; an order-P expansion in V varies at the scale of its angular resolution ``pi / P`` (the half period of
  ``Y_P``), and to first order a change of V by delta changes it by about ``P delta`` relative to its size
  (``|dY_p / dtheta| <~ p |Y_p|``). The plan keeps the global SHRM while ``P_B delta <= sqrt(epsilon)`` (that change
  stays below the tolerance's relative RMS) and switches to the local SHRM (eq. 6, per-pixel V) beyond, i.e. for
  ``d < r / sin(sqrt(epsilon) / (2 P_B))``. Lobes with P_B = 0 need no V at all (the map is indexed by R or N,
  computed per pixel), so near or far makes no difference for them;
* under a **time budget** (:func:`plan_for_budget`): the most accurate plan on a ladder of tolerances whose
  predicted seconds (``relight.costmodel``) fit, with its predicted error.

Every plan lists each effect simulated and each effect skipped with the reason (view dependence of a radially
symmetric lobe, q != 0 terms of an azimuthally symmetric one, orders above the tolerance, near-viewer variation,
shadowing and interreflection, which are not yet supported). :func:`run_plan` executes a plan, projecting the
lighting once, and writes one SHRM per object (``relight.shrm_io``), its eq. 12 map for the object's view and the
irradiance coefficients of Lambertian lobes.
"""

from __future__ import annotations

import json
import math
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, costmodel
from relight.brdf.base import Lobe, RadialLobe
from relight.errors import InputError
from relight.jsonable import jsonable as _jsonable

FloatArray = NDArray[np.float64]

#: Shapes an object may have: the analytic sphere or a mesh of ``data/meshes`` (``relight.gl.mesh.OBJECTS``).
SHAPES: tuple[str, ...] = ("sphere", "bunny", "teapot")
#: Tolerances tried under a time budget, loosest first. General (SHRM) lobes stop at 1e-3: below it the order
#: search of a microfacet lobe tabulates for minutes (App. C), more than any budget worth planning for.
BUDGET_LADDER: tuple[float, ...] = (0.3, 0.1, 0.05, 0.03, 0.01, 5e-3, 3e-3, 1e-3, 5e-4, 3e-4, 1e-4, 3e-5, 1e-5)
SHRM_MIN_EPSILON = 1e-3
#: Limits of a scene.
MAX_OBJECTS = 64
MIN_SIZE, MAX_SIZE = 8, 2048
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
_SCENE_KEYS = {"name", "environment", "objects", "epsilon", "time_budget_s", "size"}
_OBJECT_KEYS = {"name", "shape", "size", "distance", "material", "view"}

UNSUPPORTED = (
    ("shadowing", "not simulated: not yet supported (every lobe sees the whole environment; no self-occlusion)"),
    ("interreflection", "not simulated: not yet supported (objects do not light each other)"),
)


# ------------------------------------------------------------------------------------------------ scene
@dataclass(frozen=True)
class SceneObject:
    """One object of a scene (module docstring); ``material`` is the BRDF spec as given."""

    name: str
    shape: str
    size: float
    distance: float
    material: Any
    view: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "shape": self.shape, "size": self.size, "distance": self.distance,
                "material": self.material, "view": list(self.view)}


@dataclass(frozen=True)
class Scene:
    """A scene: environment (a file path, or a service envmap id), objects, and a tolerance or a time budget."""

    environment: str
    objects: tuple[SceneObject, ...]
    epsilon: float | None = None
    time_budget_s: float | None = None
    size: int | None = None
    name: str = "scene"

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "environment": self.environment, "epsilon": self.epsilon,
                "time_budget_s": self.time_budget_s, "size": self.size,
                "objects": [o.as_dict() for o in self.objects]}


def _number(where: str, value: Any, *, lo: float | None = None, lo_open: bool = True, hi: float | None = None,
            hi_open: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{where} must be finite, got {value!r}")
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise InputError(f"{where} must be {'>' if lo_open else '>='} {lo:g}, got {value!r}")
    if hi is not None and (v > hi or (hi_open and v == hi)):
        raise InputError(f"{where} must be {'<' if hi_open else '<='} {hi:g}, got {value!r}")
    return v


def _unknown(where: str, got: Mapping[str, Any], valid: set[str]) -> None:
    extra = sorted(set(got) - valid)
    if extra:
        raise InputError(f"{where}: unknown key {extra[0]!r}; valid keys are {sorted(valid)}")


def _object_from_dict(k: int, d: Any) -> SceneObject:
    from relight.brdf.spec import parse_brdf

    where = f"objects[{k}]"
    if not isinstance(d, Mapping):
        raise InputError(f"{where} must be an object, got {type(d).__name__}")
    _unknown(where, d, _OBJECT_KEYS)
    for key in ("size", "distance", "material"):
        if key not in d:
            raise InputError(f"{where}: missing {key!r}")
    name = d.get("name", f"object{k}")
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(f"{where}.name must be 1-64 letters, digits, '_', '-' or '.', got {name!r}")
    shape = d.get("shape", "sphere")
    if shape not in SHAPES:
        raise InputError(f"{where}.shape must be one of {list(SHAPES)}, got {shape!r}")
    size = _number(f"{where}.size", d["size"], lo=0.0)
    distance = _number(f"{where}.distance", d["distance"], lo=0.0)
    if distance <= size:
        raise InputError(f"{where}: the viewer must be outside the object: distance ({distance:g}) must exceed "
                         f"size ({size:g}, the bounding radius)")
    view_raw = d.get("view", [0.0, 0.0, 1.0])
    if not isinstance(view_raw, (list, tuple)) or len(view_raw) != 3:
        raise InputError(f"{where}.view must be 3 numbers (a direction toward the viewer), got {view_raw!r}")
    view = tuple(_number(f"{where}.view[{i}]", x) for i, x in enumerate(view_raw))
    n = math.sqrt(sum(x * x for x in view))
    if n == 0.0:
        raise InputError(f"{where}.view must not be the zero vector")
    material = d["material"]
    if not isinstance(material, (str, Mapping, list)):
        raise InputError(f"{where}.material must be a BRDF spec (string, object or list), got {material!r}")
    try:
        parse_brdf(material)
    except InputError as exc:
        raise InputError(f"{where}.material: {exc}") from None
    return SceneObject(name=name, shape=str(shape), size=size, distance=distance, material=material,
                       view=(view[0] / n, view[1] / n, view[2] / n))


def scene_from_dict(d: Any) -> Scene:
    """A :class:`Scene` from its JSON form (module docstring); every problem is an ``InputError`` naming the field."""
    if not isinstance(d, Mapping):
        raise InputError(f"a scene must be a JSON object, got {type(d).__name__}")
    _unknown("scene", d, _SCENE_KEYS)
    env = d.get("environment")
    if not isinstance(env, str) or not env.strip():
        raise InputError(f"scene.environment must be a non-empty string (a file path or an envmap id), got {env!r}")
    objs = d.get("objects")
    if not isinstance(objs, list) or not objs:
        raise InputError("scene.objects must be a non-empty list")
    if len(objs) > MAX_OBJECTS:
        raise InputError(f"scene.objects: at most {MAX_OBJECTS} objects, got {len(objs)}")
    objects = tuple(_object_from_dict(k, o) for k, o in enumerate(objs))
    names = [o.name for o in objects]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"scene.objects: duplicate name {dup[0]!r}")
    eps_raw, budget_raw = d.get("epsilon"), d.get("time_budget_s")
    if (eps_raw is None) == (budget_raw is None):
        raise InputError("a scene needs exactly one of epsilon (a tolerance) or time_budget_s (seconds)")
    epsilon = None if eps_raw is None else _number("scene.epsilon", eps_raw, lo=0.0, hi=1.0)
    budget = None if budget_raw is None else _number("scene.time_budget_s", budget_raw, lo=0.0)
    size_raw = d.get("size")
    size = None
    if size_raw is not None:
        if isinstance(size_raw, bool) or not isinstance(size_raw, int) or not MIN_SIZE <= size_raw <= MAX_SIZE:
            raise InputError(f"scene.size must be an integer in {MIN_SIZE}..{MAX_SIZE}, got {size_raw!r}")
        size = int(size_raw)
    name = d.get("name", "scene")
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(f"scene.name must be 1-64 letters, digits, '_', '-' or '.', got {name!r}")
    return Scene(environment=env.strip(), objects=objects, epsilon=epsilon, time_budget_s=budget, size=size,
                 name=name)


def load_scene(path: str | Path) -> Scene:
    """Read a scene JSON file; a relative environment path is resolved against the file's folder."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read scene {str(p)!r}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"scene {p.name} is not valid JSON ({exc})") from None
    scene = scene_from_dict(data)
    env = Path(scene.environment)
    if not env.is_absolute():
        env = p.resolve().parent / env
    return Scene(environment=str(env), objects=scene.objects, epsilon=scene.epsilon,
                 time_budget_s=scene.time_budget_s, size=scene.size, name=scene.name)


# ------------------------------------------------------------------------------------------------ planning
def representation_of(lobe: Lobe) -> tuple[str, str, str]:
    """(representation, SHRM structure, reason) of a lobe (module docstring)."""
    from relight.brdf.radial import Lambert

    if isinstance(lobe, Lambert):
        return ("irradiance", "radial", "Lambertian lobe: irradiance coefficients only, centred on N (seed 000 §5.2, "
                "footnote 1: F = 2, 9 coefficients)")
    if lobe.radially_symmetric:
        return ("reflection_map", "radial", f"radially symmetric lobe about {lobe.center}: one 2-D reflection map "
                "(P = 0, §3.1)")
    if lobe.azimuthally_symmetric:
        return ("shrm_q0", "azimuthal", "no azimuthal dependence: q = 0 terms only, P + 1 maps (§7.1)")
    return ("shrm", "general", "general isotropic lobe: (P + 1)^2 maps B_pq (§4)")


def view_spread(size: float, distance: float) -> float:
    """Full angle (radians) of the cone of view directions over an object: ``2 asin(r / d)``."""
    return 2.0 * math.asin(min(1.0, size / distance))


def near_threshold_distance(size: float, p_b: int, epsilon: float) -> float:
    """Distance below which the local SHRM is used: ``r / sin(sqrt(epsilon) / (2 P_B))`` (0 for P_B = 0)."""
    if p_b <= 0:
        return 0.0
    half = math.sqrt(epsilon) / (2.0 * p_b)
    return math.inf if half <= 0.0 else (size / math.sin(half) if half < math.pi / 2 else size)


def _lobe_key(lobe: Lobe) -> str:
    return json.dumps([type(lobe).__qualname__, lobe.spec()], sort_keys=True)


@dataclass
class _Choice:
    """Orders of one lobe at one tolerance (internal)."""

    lobe: Lobe
    representation: str
    structure: str
    reason: str
    f_rho: int
    p_rho: int
    eps_rho: float  # the lobe's uncaptured energy at (F_rho, P_rho)
    eps_rho_below: dict[str, float]  # at F_rho - 1 (and P_rho - 1)
    probes: tuple[tuple[int, int], ...] | None
    coefficients: Any  # lpq.BRDFCoefficients (SHRM lobes) or RadialSpectrum


def _choose(lobe: Lobe, epsilon: float) -> _Choice:
    """Smallest orders meeting ``epsilon`` for one lobe: ``spectrum_for_tolerance`` for radial lobes (as
    ``prefilter_radial``), App. C's search (``lpq.cached_select_orders``) otherwise (as ``create_shrm``)."""
    from relight.brdf import lpq
    from relight.brdf.coefficients import spectrum_for_tolerance

    representation, structure, reason = representation_of(lobe)
    if isinstance(lobe, RadialLobe):
        spec, f_rho = spectrum_for_tolerance(lobe, epsilon)
        eps = spec.epsilon()
        below = {"F_rho_minus_1": float(eps[f_rho - 1]) if f_rho > 0 else 1.0}
        return _Choice(lobe, representation, structure, reason, f_rho, 0, float(eps[min(f_rho, spec.lmax)]), below,
                       None, spec)
    sel, _ = lpq.cached_select_orders(lobe, epsilon)
    table = sel.coefficients.epsilon_table()
    below = {"F_rho_minus_1": float(table[sel.F - 1, sel.P]) if sel.F > 0 else 1.0,
             "P_rho_minus_1": float(table[sel.F, sel.P - 1]) if sel.P > 0 else 1.0}
    probes = tuple((int(h["F"]), int(h["P"])) for h in sel.history)
    if structure == "radial":
        p_rho = 0
    else:
        p_rho = sel.P
    return _Choice(lobe, representation, structure, reason, sel.F, p_rho, float(sel.epsilon_achieved), below,
                   probes, sel.coefficients)


@dataclass
class Plan:
    """A planned scene: :meth:`as_dict` is the JSON the CLI prints and the service stores."""

    scene: Scene
    data: dict[str, Any]
    lighting: Any = None  # relight.prefilter.LightingSpectrum, shared with run_plan
    choices: dict[str, _Choice] = field(default_factory=dict)
    keys: dict[str, str] = field(default_factory=dict)  # computation id -> lobe key of ``choices``

    def as_dict(self) -> dict[str, Any]:
        return self.data


def _predicted_radial(choice: _Choice, lighting: Any, epsilon: float, f_cap: int) -> tuple[int, int | None, dict[
        str, float]]:
    """F_B, F_L and predicted errors of a radial lobe, exactly as ``prefilter_radial`` (§5.1, App. B)."""
    from relight.brdf.coefficients import radial_transfer
    from relight.prefilter import choose_orders

    spec = choice.coefficients
    f_proj = min(choice.f_rho, f_cap)
    assert isinstance(choice.lobe, RadialLobe)
    transfer = spec.transfer if spec.transfer.shape[0] > f_proj else radial_transfer(choice.lobe, f_proj).transfer
    oc = choose_orders(spec, lighting, epsilon, None, choice.f_rho, f_cap, transfer)
    d = oc.as_dict()
    pred = {k: float(v) for k, v in d.items() if k.startswith(("epsilon", "rms")) and v is not None}
    return oc.F_B, oc.F_L, pred


def _predicted_shrm(choice: _Choice, lighting: Any, epsilon: float, f_cap: int) -> tuple[int, int | None, dict[
        str, float]]:
    """F_B, F_L and predicted errors of an SHRM lobe, exactly as ``create_shrm`` (§5.1, App. B generalised)."""
    from relight.orders import order_for_tolerance
    from relight.shrm import predicted_errors

    f_l = order_for_tolerance(lighting.band_energy(), lighting.total_energy, epsilon)
    f_b = min(choice.f_rho, f_cap, f_l if f_l is not None else choice.f_rho)
    return f_b, f_l, predicted_errors(choice.coefficients, lighting, f_b, choice.p_rho)


def _effects(obj: SceneObject, comps: list[dict[str, Any]], viewer: dict[str, Any], epsilon: float) -> list[dict[
        str, Any]]:
    """What is simulated and what is skipped for one object, with reasons."""
    out: list[dict[str, Any]] = []
    for c in comps:
        lobe = f"{c['kind']} ({c['center']}-centred)"
        if c["representation"] == "irradiance":
            out.append({"effect": f"diffuse reflection: {lobe}", "simulated": True,
                        "reason": f"irradiance to order F = {c['F_B']}: {(c['F_B'] + 1) ** 2} coefficients"
                        + ("" if c["F_B"] <= 2 else f" (the tolerance {epsilon:g} is below the 1/128 that F = 2 "
                           "leaves out, so F > 2)")})
        elif c["representation"] == "reflection_map":
            out.append({"effect": f"glossy reflection: {lobe}", "simulated": True,
                        "reason": f"2-D reflection map to order F = {c['F_B']}"})
        else:
            out.append({"effect": f"view-dependent reflection: {lobe}", "simulated": True,
                        "reason": f"SHRM to orders F = {c['F_B']}, P = {c['P_B']}: {c['n_maps']} maps"})
        if c["structure"] == "radial":
            out.append({"effect": f"view dependence: {lobe}", "simulated": False,
                        "reason": "BRDF is radially symmetric: it depends on the angle to its centre only (P = 0)"})
        elif c["structure"] == "azimuthal":
            out.append({"effect": f"azimuthal view dependence (q != 0): {lobe}", "simulated": False,
                        "reason": "the lobe has no azimuthal dependence: only the q = 0 terms are non-zero"})
        cut = c["F_B"] < c["F_rho"]
        out.append({"effect": f"orders above F = {c['F_B']}" + (f", P = {c['P_B']}" if c["P_B"] else "")
                    + f": {lobe}", "simulated": False,
                    "reason": (f"the lighting holds less than epsilon = {epsilon:g} of its energy above F_L = "
                               f"{c['F_L']} (minimum-of-orders rule, §5.1)") if cut else
                    (f"their share of the lobe's energy is below the tolerance: epsilon_rho = {c['epsilon_rho']:.3g} "
                     f"<= {epsilon:g} (§5.1)")})
    if viewer["view_dependent"]:
        near = viewer["viewer"] == "near"
        out.append({"effect": "near-viewer variation of the view direction (local SHRM, eq. 6)", "simulated": near,
                    "reason": (f"view spread {viewer['view_spread_deg']:.3g} deg over the object: P_B delta = "
                               f"{viewer['p_delta']:.3g} {'>' if near else '<='} sqrt(epsilon) = "
                               f"{math.sqrt(epsilon):.3g}; " + ("local SHRM, V per pixel" if near else
                                                                 "one V for the object (global SHRM, eq. 7)"))})
    else:
        out.append({"effect": "near-viewer variation of the view direction", "simulated": False,
                    "reason": "no view-dependent lobe: every map is indexed by R or N, computed per pixel, exact "
                    "for any viewer distance"})
    out.append({"effect": f"shape: {obj.shape}", "simulated": True,
                "reason": "the maps do not depend on the shape; it only sets the normals looked up per pixel"})
    out.append({"effect": "parallax of the environment", "simulated": False,
                "reason": "the environment is distant (seed 000 §3): the same lighting at every point"})
    for effect, reason in UNSUPPORTED:
        out.append({"effect": effect, "simulated": False, "reason": reason})
    return out


def _plan_at(
    scene: Scene, pixels: FloatArray, epsilon: float, cal: costmodel.Calibration, lighting: Any = None
) -> Plan:
    """Plan every object at one tolerance (module docstring)."""
    from relight.brdf.spec import parse_brdf
    from relight.prefilter import project_lighting, size_for_order
    from relight.shrm import brdf_lobes

    h, w = pixels.shape[:2]
    f_cap = h - 1
    choices: dict[str, _Choice] = {}
    obj_lobes: list[list[str]] = []
    t_brdf = time.perf_counter()
    for obj in scene.objects:
        keys = []
        for lobe in brdf_lobes(parse_brdf(obj.material)):
            key = _lobe_key(lobe)
            if key not in choices:
                choices[key] = _choose(lobe, epsilon)
            keys.append(key)
        obj_lobes.append(keys)
    t_brdf = time.perf_counter() - t_brdf
    f_proj = min(max(c.f_rho for c in choices.values()), f_cap)
    t_proj = 0.0
    if lighting is None or lighting.lmax < f_proj:
        t0 = time.perf_counter()
        lighting = project_lighting(pixels, f_proj)
        t_proj = time.perf_counter() - t0

    lobe_info: dict[str, dict[str, Any]] = {}
    for key, c in choices.items():
        if c.structure == "radial":
            f_b, f_l, errors = _predicted_radial(c, lighting, epsilon, f_cap)
        else:
            f_b, f_l, errors = _predicted_shrm(c, lighting, epsilon, f_cap)
        lobe_info[key] = {"F_B": int(f_b), "F_L": f_l, "predicted": errors}

    computations: dict[tuple[str, int], dict[str, Any]] = {}
    objects: list[dict[str, Any]] = []
    for obj, lobe_keys in zip(scene.objects, obj_lobes, strict=True):
        s = scene.size if scene.size is not None else size_for_order(max(lobe_info[k]["F_B"] for k in lobe_keys))
        comps = []
        for key in lobe_keys:
            c, info = choices[key], lobe_info[key]
            ck = (key, s)
            if ck not in computations:
                n = costmodel.n_maps(c.structure, c.p_rho)
                computations[ck] = {
                    "id": f"c{len(computations)}", "lobe": c.lobe.spec(), "kind": c.lobe.kind, "center": c.lobe.center,
                    "representation": c.representation, "structure": c.structure, "reason": c.reason,
                    "F_rho": c.f_rho, "P_rho": c.p_rho, "F_L": info["F_L"], "F_B": info["F_B"], "P_B": c.p_rho,
                    "n_maps": n, "n_coefficients": (info["F_B"] + 1) ** 2 * n, "size": s,
                    "epsilon_rho": c.eps_rho, "epsilon_rho_below": c.eps_rho_below,
                    "predicted": info["predicted"], "shared_by": [],
                    "order_search_probes": [list(p) for p in c.probes] if c.probes else None,
                }
            computations[ck]["shared_by"].append(obj.name)
            comps.append(computations[ck])
        delta = view_spread(obj.size, obj.distance)
        p_max = max((c["P_B"] for c in comps if c["structure"] != "radial"), default=0)
        view_dependent = p_max > 0
        near = view_dependent and p_max * delta > math.sqrt(epsilon)
        viewer = {
            "view_dependent": view_dependent, "viewer": "near" if near else "distant",
            "shrm": ("local (eq. 6)" if near else "global (eq. 7)") if view_dependent else "none (P = 0)",
            "view_spread_deg": math.degrees(delta), "p_delta": p_max * delta,
            "near_below_distance": near_threshold_distance(obj.size, p_max, epsilon),
        }
        worst = max(comps, key=lambda c: c["predicted"].get("epsilon_min_of_errors", 0.0))
        objects.append({
            **obj.as_dict(), **viewer, "output_rows": s, "computations": [c["id"] for c in comps],
            "predicted_error": {k: worst["predicted"].get(k) for k in (
                "rms_min_of_errors", "rms_appendix_b", "epsilon_min_of_errors", "epsilon_appendix_b")},
            "effects": _effects(obj, comps, viewer, epsilon),
        })

    comp_list = list(computations.values())
    brdf_parts = []
    for key, c in choices.items():
        if c.structure == "radial":  # the order search, then the coefficients at every F_B used (compute_component)
            f_bs = {int(cc["F_B"]) for (k, _), cc in computations.items() if k == key}
            probes = [(f, 0) for f in costmodel.radial_probes(c.lobe, c.f_rho, explicit=False)] + [
                (f, 0) for f in sorted(f_bs)]
            brdf_parts.append(costmodel.brdf_features(c.lobe, c.f_rho, 0, explicit=False, probes=probes))
        else:
            brdf_parts.append(costmodel.brdf_features(c.lobe, c.f_rho, c.p_rho, explicit=False, search="lpq",
                                                      probes=c.probes))
    feats = costmodel.add_features(
        costmodel.projection_features(h, w, f_proj), {"call": 1.0, "conv": float((f_proj + 1) ** 2)},
        *brdf_parts,
        *(costmodel.synthesis_features(c["size"], c["F_B"], *costmodel.synthesis_counts(c["structure"], c["P_B"],
                                                                                        c["F_B"]))
          for c in comp_list),
        *(costmodel.view_features([(c["structure"], c["P_B"], c["center"]) for c in comp_list
                                   if c["id"] in o["computations"]], o["output_rows"]) for o in objects),
    )
    pred = cal.predict(feats)
    worst_obj = max(objects, key=lambda o: o["predicted_error"]["epsilon_min_of_errors"] or 0.0)
    data = {
        "format": "relight-scene-plan", "relight_version": __version__, "scene": scene.name,
        "environment": scene.environment, "epsilon": epsilon, "time_budget_s": scene.time_budget_s,
        "mode": "tolerance" if scene.time_budget_s is None else "time_budget",
        "lighting": {"F_proj": f_proj, "projected_once": True, "input": {"height": h, "width": w},
                     "seconds": t_proj,
                     "shared_by": [o.name for o in scene.objects],
                     "reason": "projected once to the largest order any lobe needs, then shared (App. C)"},
        "computations": comp_list, "objects": objects, "brdf_seconds": t_brdf,
        "predicted_seconds": pred.seconds, "predicted_stages": pred.stages,
        "predicted_error": worst_obj["predicted_error"],
        "cost_model": {"calibrated": cal.calibrated, "key": cal.key,
                       "note": "includes the BRDF order search and coefficients, the projection, every map and "
                               "one eq. 12 view per object; not file writing"},
    }
    ids = {c["id"]: key for (key, _), c in computations.items()}
    return Plan(scene=scene, data=data, lighting=lighting, choices=choices, keys=ids)


def _pixels(pixels: NDArray[np.floating]) -> FloatArray:
    """The environment map as float64 (H, W, 3), validated by ``require_rgb_latlong``."""
    from relight.conventions import require_rgb_latlong

    return np.asarray(require_rgb_latlong(pixels), dtype=np.float64)



def plan_scene(
    scene: Scene, pixels: NDArray[np.floating], *, calibration: costmodel.Calibration | None = None
) -> Plan:
    """Plan a scene for an environment map (H, W, 3): at its tolerance, or under its time budget."""
    px = _pixels(pixels)
    cal = calibration if calibration is not None else costmodel.load_calibration()
    if scene.time_budget_s is not None:
        return plan_for_budget(scene, px, scene.time_budget_s, calibration=cal)
    assert scene.epsilon is not None
    return _plan_at(scene, px, scene.epsilon, cal)


def plan_for_budget(
    scene: Scene, pixels: NDArray[np.floating], budget_s: float, *, calibration: costmodel.Calibration | None = None,
    ladder: Sequence[float] = BUDGET_LADDER,
) -> Plan:
    """The most accurate plan on ``ladder`` whose predicted seconds fit ``budget_s`` (module docstring).

    Predicted time grows as the tolerance tightens; the ladder is walked from the loosest tolerance and stops at the
    first plan over budget. If even the loosest does not fit, that plan is returned with ``budget_met = False``.
    """
    from relight.brdf.spec import parse_brdf
    from relight.shrm import brdf_lobes

    px = _pixels(pixels)
    cal = calibration if calibration is not None else costmodel.load_calibration()
    general = any(not lobe.radially_symmetric for o in scene.objects for lobe in brdf_lobes(parse_brdf(o.material)))
    steps = [e for e in ladder if not (general and e < SHRM_MIN_EPSILON)]
    tried: list[dict[str, Any]] = []
    best: Plan | None = None
    lighting = None
    for eps in steps:
        plan = _plan_at(scene, px, eps, cal, lighting)
        lighting = plan.lighting
        fits = plan.data["predicted_seconds"] <= budget_s
        tried.append({"epsilon": eps, "predicted_seconds": plan.data["predicted_seconds"], "fits": fits,
                      "predicted_rms": plan.data["predicted_error"]["rms_min_of_errors"]})
        if not fits:
            if best is None:
                best = plan
            break
        best = plan
    assert best is not None
    best.data["time_budget_s"] = budget_s
    best.data["budget_met"] = bool(best.data["predicted_seconds"] <= budget_s)
    best.data["budget_ladder"] = tried
    if general:
        best.data["budget_note"] = (f"tolerances below {SHRM_MIN_EPSILON:g} are not tried for general lobes: their "
                                    "order search alone takes minutes (App. C)")
    return best


def format_plan(plan: Plan) -> str:
    """The plan as text: objects, computations with orders and reasons, effects, predicted error and time."""
    d = plan.data
    lines = [f"scene {d['scene']}: environment {d['environment']} ({d['lighting']['input']['width']} x "
             f"{d['lighting']['input']['height']})"]
    if d["mode"] == "time_budget":
        lines.append(f"  time budget {d['time_budget_s']:g} s -> epsilon {d['epsilon']:g}"
                     + ("" if d.get("budget_met") else "  (over budget even at the loosest tolerance)"))
    else:
        lines.append(f"  tolerance epsilon {d['epsilon']:g}")
    lines.append(f"  lighting projected once to F = {d['lighting']['F_proj']}, shared by "
                 f"{len(d['lighting']['shared_by'])} object(s)")
    for c in d["computations"]:
        lines.append(f"  [{c['id']}] {c['kind']} ({c['center']}): {c['representation']}, F_B = {c['F_B']}, "
                     f"P_B = {c['P_B']}, {c['n_maps']} map(s) of {c['size']} x {2 * c['size']}; shared by "
                     f"{', '.join(c['shared_by'])}")
        lines.append(f"       {c['reason']}")
    for o in d["objects"]:
        pe = o["predicted_error"]["rms_min_of_errors"]
        lines.append(f"  object {o['name']} ({o['shape']}, size {o['size']:g} at distance {o['distance']:g}): "
                     f"{o['viewer']} viewer, SHRM {o['shrm']}, predicted relative RMS {pe:.3g}")
        for e in o["effects"]:
            lines.append(f"    {'+' if e['simulated'] else '-'} {e['effect']}: {e['reason']}")
    lines.append(f"  predicted {d['predicted_seconds']:.3g} s, worst predicted relative RMS "
                 f"{d['predicted_error']['rms_min_of_errors']:.3g}")
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ execution
def compute_component(plan: Plan, comp: Mapping[str, Any]) -> Any:
    """One computation of a plan as an ``relight.shrm.SHRMComponent`` from the plan's shared lighting (App. C
    steps 2–3: ``B_lmpq = L_lm rho_hat_lpq`` synthesised into the local maps)."""
    from relight.brdf import lpq
    from relight.shrm import SHRMComponent, synthesize_local, terms_for

    choice = plan.choices[plan.keys[str(comp["id"])]]
    f_b, p_b, s = int(comp["F_B"]), int(comp["P_B"]), int(comp["size"])
    if choice.structure == "radial":
        coeffs = lpq.brdf_coefficients(choice.lobe, f_b, 0)  # rho_hat_l00 = sqrt(4 pi) rho_l (exact)
    else:
        coeffs = choice.coefficients
    rho = coeffs.rho[: f_b + 1, : p_b + 1, : min(coeffs.Q, p_b) + 1]
    terms = terms_for(choice.structure, p_b)  # type: ignore[arg-type]
    maps = synthesize_local(plan.lighting.alm, plan.lighting.lmax, rho, terms, s)
    report = {"center": choice.lobe.center, "structure": choice.structure, "reason": comp["reason"],
              "lobe": choice.lobe.spec(), "orders": {"F_B": f_b, "P_B": p_b, "F_rho": comp["F_rho"],
                                                     "F_L": comp["F_L"]},
              "n_maps": len(terms), "predicted": comp["predicted"]}
    return SHRMComponent(center=str(choice.lobe.center), structure=choice.structure,  # type: ignore[arg-type]
                         F=f_b, P=p_b, terms=terms, maps=maps, lobe=choice.lobe.spec(), report=report)


def irradiance_coefficients(plan: Plan, comp: Mapping[str, Any]) -> list[list[float]]:
    """Real SH coefficients (3 colours x (F + 1)^2) of a Lambertian lobe's output ``E(N) / pi`` times albedo."""
    from relight import sh
    from relight.brdf.coefficients import radial_transfer

    lobe = plan.choices[plan.keys[str(comp["id"])]].lobe
    f_b = int(comp["F_B"])
    assert isinstance(lobe, RadialLobe)
    transfer = radial_transfer(lobe, f_b).transfer  # (F+1, C)
    alm = sh.truncate(plan.lighting.alm, plan.lighting.lmax, f_b)
    l_idx, _ = sh.lm_arrays(f_b)
    b = alm * transfer[l_idx].T
    return [[float(x) for x in row] for row in sh.to_real(b, f_b)]


def run_plan(
    plan: Plan, out_dir: str | Path | None = None, *, write: bool = True, preview_size: int = 0
) -> dict[str, Any]:
    """Execute a plan: every computation once from the plan's lighting (projected once, while planning), then per
    object its SHRM, the eq. 12 map for its view (global SHRM) and, if asked, a sphere preview (local SHRM, eq. 6,
    for near viewers).

    Returns the result summary (also ``result.json`` next to ``plan.json`` in ``out_dir``): files, orders, measured
    seconds per stage next to the predicted ones. With ``write=False`` nothing is written and the view maps and
    SHRMs are returned under ``"maps"`` and ``"shrms"`` (``{object name: ...}``).
    """
    from relight.shrm import SHRM, reflect, render_sphere

    if plan.lighting is None or plan.lighting.lmax < int(plan.data["lighting"]["F_proj"]):
        raise InputError("this plan has no lighting to the planned order attached; plan it again with plan_scene")
    out = Path(out_dir) if out_dir is not None else None
    if write:
        if out is None:
            raise InputError("run_plan needs an output folder to write to")
        out.mkdir(parents=True, exist_ok=True)
    # the order search (BRDF coefficients) and the lighting projection ran while planning
    stages: dict[str, float] = {"brdf_coefficients": float(plan.data.get("brdf_seconds", 0.0)),
                                "lighting_projection": float(plan.data["lighting"].get("seconds", 0.0))}

    def lap(stage: str, t0: float) -> float:
        now = time.perf_counter()
        stages[stage] = stages.get(stage, 0.0) + now - t0
        return now

    t = time.perf_counter()
    comps = {c["id"]: compute_component(plan, c) for c in plan.data["computations"]}
    t = lap("synthesis", t)
    objects: list[dict[str, Any]] = []
    maps: dict[str, FloatArray] = {}
    shrms: dict[str, Any] = {}
    for o in plan.data["objects"]:
        shrm = SHRM(components=[comps[i] for i in o["computations"]], brdf=None, report={
            "representation": "shrm", "layout": "local", "relight_version": __version__,
            "predicted": o["predicted_error"], "scene": plan.data["scene"], "object": o["name"]})
        image = reflect(shrm, o["view"])
        t = lap("view", t)
        entry: dict[str, Any] = {"name": o["name"], "viewer": o["viewer"], "shrm": o["shrm"],
                                 "output_rows": o["output_rows"], "files": {}}
        irr = [c for c in plan.data["computations"] if c["id"] in o["computations"]
               and c["representation"] == "irradiance"]
        if irr:
            entry["irradiance_real_sh"] = {c["id"]: irradiance_coefficients(plan, c) for c in irr}
        if write and out is not None:
            from relight.envmap import write_exr, write_png_preview
            from relight.shrm_io import write_shrm

            shrm_path = out / f"{o['name']}.shrm.exr"
            write_shrm(shrm_path, shrm)
            view_path = out / f"{o['name']}.view.exr"
            write_exr(view_path, image.astype(np.float32))
            entry["files"] = {"shrm": shrm_path.name, "manifest": shrm_path.with_suffix(".json").name,
                              "view_map": view_path.name}
            if preview_size > 0:
                sphere = render_sphere(shrm, o["view"], preview_size, local=o["viewer"] == "near")
                png = out / f"{o['name']}.sphere.png"
                write_png_preview(png, sphere)
                entry["files"]["sphere_png"] = png.name
            t = lap("writing", t)
        else:
            maps[o["name"]] = image
            shrms[o["name"]] = shrm
        objects.append(entry)
    result: dict[str, Any] = {
        "format": "relight-scene-result", "relight_version": __version__, "scene": plan.data["scene"],
        "epsilon": plan.data["epsilon"], "objects": objects,
        "computed": [c["id"] for c in plan.data["computations"]],
        "lighting_projections": 1,
        "measured_seconds": float(sum(v for k, v in stages.items() if k != "writing")),
        "measured_stages": stages,
        "predicted_seconds": plan.data["predicted_seconds"], "predicted_stages": plan.data["predicted_stages"],
    }
    if write and out is not None:
        (out / "plan.json").write_text(plan_json(plan))
        (out / "result.json").write_text(json.dumps(_jsonable(result), indent=1, allow_nan=False))
    else:
        result["maps"] = maps
        result["shrms"] = shrms
    return result




def plan_json(plan: Plan) -> str:
    """The plan as strict JSON (non-finite numbers as null)."""
    return json.dumps(_jsonable(plan.data), indent=1, allow_nan=False)
