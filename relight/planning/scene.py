"""A scene for the planner: an environment, objects and a tolerance or a time budget (seed 000 §3.1, §5.1).

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
SCENE_KEYS = frozenset({"name", "environment", "objects", "epsilon", "time_budget_s", "size"})
OBJECT_KEYS = frozenset({"name", "shape", "size", "distance", "material", "view"})
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


def _unknown(where: str, got: Mapping[str, Any], valid: frozenset[str]) -> None:
    extra = sorted(set(got) - valid)
    if extra:
        raise InputError(f"{where}: unknown key {extra[0]!r}; valid keys are {sorted(valid)}")


def _name(where: str, name: Any) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(f"{where} must be 1-64 letters, digits, '_', '-' or '.', got {name!r}")
    return name


def _object_from_dict(k: int, d: Any) -> SceneObject:
    from relight.brdf.spec import parse_brdf

    where = f"objects[{k}]"
    if not isinstance(d, Mapping):
        raise InputError(f"{where} must be an object, got {type(d).__name__}")
    _unknown(where, d, OBJECT_KEYS)
    for key in ("size", "distance", "material"):
        if key not in d:
            raise InputError(f"{where}: missing {key!r}")
    name = _name(f"{where}.name", d.get("name", f"object{k}"))
    shape = d.get("shape", "sphere")
    if shape not in SHAPES:
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
        parse_brdf(material)
    except InputError as exc:
        raise InputError(f"{where}.material: {exc}") from None
    return SceneObject(name=name, shape=str(shape), size=size, distance=distance, material=material,
                       view=(view[0] / n, view[1] / n, view[2] / n))


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
    return replace(scene, environment=str(env))
