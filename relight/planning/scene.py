"""A scene for the planner: an environment, objects and a tolerance or a time budget (seed 000 §3.1, §5.1), with
planner v2's inputs (issue 16 item 4): per object ``shadows``, ``interreflections``, ``mesh`` and ``tangent``, per
scene ``lighting``, ``material_edits`` and ``frame_budget_ms``.

One schema: :func:`scene_from_dict` validates a scene's JSON form strictly against the limits named here, and the
API's ``SceneCreate`` takes its limits from the same constants. Every object has a shape (the analytic sphere or a
mesh), a bounding radius ``size``, the ``distance`` from the viewer to its centre, the direction ``view`` from the
object toward the viewer and a material (a BRDF spec, possibly a sum of lobes).

The limits bound what one scene holds in memory: :func:`relight.planning.run_plan` keeps every computation's maps
(up to ``(P + 1)^2`` maps of ``S x 2S x 3`` float64 per lobe) until the objects are written, so a scene allows
fewer objects (:data:`MAX_SCENE_OBJECTS`) and smaller maps (:data:`MAX_SCENE_SIZE`) than a single prefilter job.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from relight.errors import InputError
from relight.shapes import SHAPES as SHAPES  # re-exported: the scene schema names its shapes

#: Most objects in a scene: every object's maps are held in memory at once while the scene runs, and the viewer draws
#: them all (module docstring).
MAX_SCENE_OBJECTS = 16
#: Output rows S a scene may ask for explicitly (``size``; the default follows S ~ 10 F, seed 000 §5.2): a microfacet
#: lobe at epsilon = 1e-3 needs (P + 1)^2 ~ 300 maps, about 3.6 GB of float64 at S = 512.
MIN_SCENE_SIZE, MAX_SCENE_SIZE = 8, 512
#: Longest time budget, seconds (one hour: the budget ladder is walked by predicting, not by running).
MAX_TIME_BUDGET_S = 3600.0
#: Largest bounding radius and viewer distance (scene units): beyond them ``asin(r / d)`` loses nothing but the
#: numbers stop being a scene (1e6 and 1e9 keep ``r / d`` and its square exact in float64).
MAX_OBJECT_SIZE = 1e6
MAX_OBJECT_DISTANCE = 1e9
#: Names of scenes and objects: 1-64 letters, digits, '_', '-' or '.', starting with a letter or digit (file names).
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
_NAME = re.compile(NAME_PATTERN)
SCENE_KEYS = frozenset({"name", "environment", "objects", "epsilon", "time_budget_s", "size", "lighting",
                        "material_edits", "frame_budget_ms"})
OBJECT_KEYS = frozenset({"name", "shape", "size", "distance", "material", "view", "shadows", "interreflections",
                         "mesh", "tangent"})
#: Per object: which shadows to simulate (planner v2, issue 16 item 4). ``auto``: on for meshes, off for the analytic
#: sphere (convex: it never shadows itself); ``approximate`` accepts seed 002's visibility at each lobe's centre,
#: ``exact`` asks for shadows exact within the lighting's order (transfer inside the integral: seeds 003, 004).
SHADOW_MODES: tuple[str, ...] = ("auto", "none", "approximate", "exact")
#: Per scene: how the lighting changes while the viewer runs. ``rotating``: the environment turns (free for every
#: representation: rotate N and V, or the SH lighting vector); ``dynamic``: new lighting every frame (moving area
#: lights, video environments), which only SH-lighting representations absorb without a new precomputation.
LIGHTING_MODES: tuple[str, ...] = ("static", "rotating", "dynamic")
#: Tangent fields of anisotropic materials (``relight.sh_render.frames_for``): the azimuthal field about +Y, the
#: projection of a constant direction (Kautz et al. 2002's brushing direction), or the mesh's own tangents.
TANGENT_KINDS: tuple[str, ...] = ("azimuthal", "project", "mesh")
#: Largest per-frame budget, milliseconds (one second per frame is no longer interactive).
MAX_FRAME_BUDGET_MS = 1000.0
#: Mesh references: a file path (CLI) or a mesh id from ``POST /meshes`` (the service): 1-512 printable characters.
MAX_MESH_REF = 512
#: Direction toward the viewer when an object gives none (+Z).
DEFAULT_VIEW: tuple[float, float, float] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class SceneObject:
    """One object of a scene (module docstring); ``material`` is the BRDF spec as given, ``view`` a unit vector."""

    name: str
    shape: str
    size: float
    distance: float
    material: Any
    view: tuple[float, float, float] = DEFAULT_VIEW
    shadows: str = "auto"
    interreflections: bool = False
    mesh: str | None = None  # an uploaded mesh (path or id); ``shape`` is then "mesh"
    tangent: dict[str, Any] | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "shape": self.shape, "size": self.size, "distance": self.distance,
                "material": self.material, "view": list(self.view)}

    @property
    def is_mesh(self) -> bool:
        """Drawn from a mesh (a sample mesh or an uploaded one), not the analytic sphere."""
        return self.shape != "sphere"

    @property
    def mesh_ref(self) -> str | None:
        """The mesh's name: the uploaded mesh's reference, the sample mesh's name, None for the sphere."""
        return self.mesh if self.mesh is not None else (self.shape if self.is_mesh else None)

    @property
    def shadowed(self) -> str:
        """The shadows asked for, ``auto`` resolved: none on the sphere (convex), else the request (auto: exact if
        affordable, decided per lobe by the planner)."""
        if not self.is_mesh:
            return "none"
        return self.shadows


@dataclass(frozen=True)
class Scene:
    """A scene: environment (a file path, or a service envmap id), objects, and a tolerance or a time budget."""

    environment: str
    objects: tuple[SceneObject, ...]
    epsilon: float | None = None
    time_budget_s: float | None = None
    size: int | None = None
    name: str = "scene"
    lighting: str = "static"
    material_edits: tuple[str, ...] = ()  # names of the objects whose material is edited live
    frame_budget_ms: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "environment": self.environment, "epsilon": self.epsilon,
                "time_budget_s": self.time_budget_s, "size": self.size,
                "objects": [o.as_dict() for o in self.objects]}

    def edited(self, name: str) -> bool:
        return name in self.material_edits


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


def _unknown(where: str, got: Mapping[str, Any], valid: frozenset[str]) -> None:
    extra = sorted(set(got) - valid)
    if extra:
        raise InputError(f"{where}: unknown key {extra[0]!r}; valid keys are {sorted(valid)}")


def _name(where: str, name: Any) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(f"{where} must be 1-64 letters, digits, '_', '-' or '.', got {name!r}")
    return name


def _object_from_dict(k: int, d: Any) -> SceneObject:
    from relight.brdf.spec import parse_frame_brdf

    where = f"objects[{k}]"
    if not isinstance(d, Mapping):
        raise InputError(f"{where} must be an object, got {type(d).__name__}")
    _unknown(where, d, OBJECT_KEYS)
    for key in ("size", "distance", "material"):
        if key not in d:
            raise InputError(f"{where}: missing {key!r}")
    name = _name(f"{where}.name", d.get("name", f"object{k}"))
    mesh = d.get("mesh")
    if mesh is not None:
        if not isinstance(mesh, str) or not 0 < len(mesh.strip()) <= MAX_MESH_REF or not mesh.isprintable():
            raise InputError(f"{where}.mesh must be a mesh file path or a mesh id (1-{MAX_MESH_REF} printable "
                             f"characters), got {mesh!r}")
        if "shape" in d:
            raise InputError(f"{where}: give either shape (a sample shape) or mesh (an uploaded mesh), not both")
        mesh = mesh.strip()
    shape = "mesh" if mesh is not None else d.get("shape", "sphere")
    if mesh is None and shape not in SHAPES:
        raise InputError(f"{where}.shape must be one of {list(SHAPES)}, got {shape!r}")
    size = _number(f"{where}.size", d["size"], lo=0.0, hi=MAX_OBJECT_SIZE, hi_open=False)
    distance = _number(f"{where}.distance", d["distance"], lo=0.0, hi=MAX_OBJECT_DISTANCE, hi_open=False)
    if distance <= size:
        raise InputError(f"{where}: the viewer must be outside the object: distance ({distance:g}) must exceed "
                         f"size ({size:g}, the bounding radius)")
    view_raw = d.get("view", list(DEFAULT_VIEW))
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
        parse_frame_brdf(material)  # isotropic, anisotropic (seed 003) or measured
    except InputError as exc:
        raise InputError(f"{where}.material: {exc}") from None
    shadows = d.get("shadows", "auto")
    if shadows not in SHADOW_MODES:
        raise InputError(f"{where}.shadows must be one of {list(SHADOW_MODES)}, got {shadows!r}")
    inter = d.get("interreflections", False)
    if not isinstance(inter, bool):
        raise InputError(f"{where}.interreflections must be true or false, got {inter!r}")
    tangent = _tangent(f"{where}.tangent", d.get("tangent"), shape)
    return SceneObject(name=name, shape=str(shape), size=size, distance=distance, material=material,
                       view=(view[0] / n, view[1] / n, view[2] / n), shadows=str(shadows), interreflections=inter,
                       mesh=mesh, tangent=tangent)


def _tangent(where: str, t: Any, shape: str) -> dict[str, Any] | None:
    """A tangent field (:data:`TANGENT_KINDS`): ``{"kind": "azimuthal"[, "axis": v]}``, ``{"kind": "project",
    "direction": v}`` or ``{"kind": "mesh"}`` (the mesh's own tangents: meshes only)."""
    if t is None:
        return None
    if not isinstance(t, Mapping) or t.get("kind") not in TANGENT_KINDS:
        raise InputError(f"{where} must be an object with kind one of {list(TANGENT_KINDS)}, got {t!r}")
    kind = str(t["kind"])
    keys = {"azimuthal": {"kind", "axis"}, "project": {"kind", "direction"}, "mesh": {"kind"}}[kind]
    _unknown(where, t, frozenset(keys))
    out: dict[str, Any] = {"kind": kind}
    for key in sorted(keys - {"kind"}):
        if key not in t:
            if kind == "project":
                raise InputError(f"{where}: kind 'project' needs a direction (3 numbers)")
            continue
        v = t[key]
        if not isinstance(v, (list, tuple)) or len(v) != 3:
            raise InputError(f"{where}.{key} must be 3 numbers, got {v!r}")
        vec = [_number(f"{where}.{key}[{i}]", x) for i, x in enumerate(v)]
        if not any(vec):
            raise InputError(f"{where}.{key} must not be the zero vector")
        out[key] = vec
    if kind == "mesh" and shape == "sphere":
        raise InputError(f"{where}: kind 'mesh' needs a mesh (the analytic sphere has no stored tangents)")
    return out


def scene_from_dict(d: Any) -> Scene:
    """A :class:`Scene` from its JSON form (module docstring); every problem is an ``InputError`` naming the field."""
    if not isinstance(d, Mapping):
        raise InputError(f"a scene must be a JSON object, got {type(d).__name__}")
    _unknown("scene", d, SCENE_KEYS)
    env = d.get("environment")
    if not isinstance(env, str) or not env.strip():
        raise InputError(f"scene.environment must be a non-empty string (a file path or an envmap id), got {env!r}")
    objs = d.get("objects")
    if not isinstance(objs, list) or not objs:
        raise InputError("scene.objects must be a non-empty list")
    if len(objs) > MAX_SCENE_OBJECTS:
        raise InputError(f"scene.objects: at most {MAX_SCENE_OBJECTS} objects, got {len(objs)}")
    objects = tuple(_object_from_dict(k, o) for k, o in enumerate(objs))
    names = [o.name for o in objects]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"scene.objects: duplicate name {dup[0]!r}")
    eps_raw, budget_raw = d.get("epsilon"), d.get("time_budget_s")
    if (eps_raw is None) == (budget_raw is None):
        raise InputError("a scene needs exactly one of epsilon (a tolerance) or time_budget_s (seconds)")
    epsilon = None if eps_raw is None else _number("scene.epsilon", eps_raw, lo=0.0, hi=1.0)
    budget = None if budget_raw is None else _number("scene.time_budget_s", budget_raw, lo=0.0,
                                                     hi=MAX_TIME_BUDGET_S, hi_open=False)
    size_raw = d.get("size")
    size = None
    if size_raw is not None:
        if (isinstance(size_raw, bool) or not isinstance(size_raw, int)
                or not MIN_SCENE_SIZE <= size_raw <= MAX_SCENE_SIZE):
            raise InputError(f"scene.size must be an integer in {MIN_SCENE_SIZE}..{MAX_SCENE_SIZE}, got {size_raw!r}")
        size = int(size_raw)
    name = _name("scene.name", d.get("name", "scene"))
    lighting = d.get("lighting", "static")
    if lighting not in LIGHTING_MODES:
        raise InputError(f"scene.lighting must be one of {list(LIGHTING_MODES)}, got {lighting!r}")
    edits_raw = d.get("material_edits", False)
    if isinstance(edits_raw, bool):
        edits = tuple(names) if edits_raw else ()
    elif isinstance(edits_raw, list) and all(isinstance(x, str) for x in edits_raw):
        missing = sorted(set(edits_raw) - set(names))
        if missing:
            raise InputError(f"scene.material_edits names no object {missing[0]!r}; objects are {names}")
        edits = tuple(x for x in names if x in edits_raw)
    else:
        raise InputError(f"scene.material_edits must be true, false or a list of object names, got {edits_raw!r}")
    fb_raw = d.get("frame_budget_ms")
    frame_budget = None if fb_raw is None else _number("scene.frame_budget_ms", fb_raw, lo=0.0,
                                                       hi=MAX_FRAME_BUDGET_MS, hi_open=False)
    return Scene(environment=env.strip(), objects=objects, epsilon=epsilon, time_budget_s=budget, size=size,
                 name=name, lighting=str(lighting), material_edits=edits, frame_budget_ms=frame_budget)


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
    base = p.resolve().parent
    env = Path(scene.environment)
    if not env.is_absolute():
        env = base / env
    objects = tuple(o if o.mesh is None or Path(o.mesh).is_absolute() else replace(o, mesh=str(base / o.mesh))
                    for o in scene.objects)
    return replace(scene, environment=str(env), objects=objects)
