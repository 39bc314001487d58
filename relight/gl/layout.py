"""Texture layout of an SHRM for the shaders: which layers form which component, and how each is weighted.

A result's manifest (``GET /shrms/{id}``, ``worker/results.py``; or ``relight.shrm_io.manifest``) lists its
layers ``{index, name, p, q}`` and, for an SHRM, its components. :func:`from_manifest` turns it into a
:class:`Layout`: components with a centre (``R``, ``N``, ``T``), a *frame* saying what the layers hold
(``relight.gl.shaders.FRAMES``) and the layers, ordered so that each component's layers are contiguous in the
texture array (``texture_order`` maps texture layer -> manifest layer). :func:`defines` gives the shader tables
of ``web/shaders/shrm.glsl``. ``web/src/layout.js`` implements the same rules (tested on the same fixtures).

Manifest fields read (all others are ignored):

* ``height``, ``width``; ``representation`` (``"reflection_map"``: one plain map, weight 1; else an SHRM);
* ``layers[*].index``, ``.p``, ``.q``, and the component k from ``.component`` or the ``.name``
  ``c<k>.p<p>.q<q>`` (``relight.shrm_io``);
* ``components[*]`` or, in the service's manifest, ``orders.components[*]`` (optional; entry k is component k):
  ``center``, ``layers`` (names or indices; default: the layers of component k), ``frame`` or ``layout``;
* ``center`` (top level: the centre of a single-component result), ``layout`` (``"local"`` / ``"global"``: what
  SHRM layers hold when a component does not say; default ``"local"``, what ``relight.shrm`` produces);
* ``files["coefficients.bin"].shape`` ``[layers, height, width, 3]`` (checked against the above when present).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError
from relight.gl.shaders import CENTERS, FRAMES
from relight.indexing import full_index

_LAYER_NAME = re.compile(r"^c(\d+)\.p(\d+)\.q(-?\d+)$")
DEFAULT_SHRM_FRAME = "local"


@dataclass(frozen=True)
class LayerRef:
    """One texture layer: its manifest index and its SH term (p, q) (real basis, index p^2 + p + q)."""

    index: int
    p: int
    q: int

    @property
    def sh_index(self) -> int:
        return full_index(self.p, self.q)


@dataclass(frozen=True)
class Component:
    center: str
    frame: str
    layers: tuple[LayerRef, ...]

    @property
    def P(self) -> int:
        return max(layer.p for layer in self.layers)


@dataclass(frozen=True)
class Layout:
    height: int
    width: int
    components: tuple[Component, ...]

    @property
    def texture_order(self) -> list[int]:
        """Manifest layer index of each texture layer (components contiguous, in order)."""
        return [layer.index for c in self.components for layer in c.layers]

    @property
    def num_layers(self) -> int:
        return sum(len(c.layers) for c in self.components)

    @property
    def sh_order(self) -> int:
        """The largest P of the components whose weights the shader evaluates (0 if none)."""
        return max([c.P for c in self.components if c.frame != "map"], default=0)


def _component_of(name: str) -> int | None:
    m = _LAYER_NAME.match(name or "")
    return int(m.group(1)) if m else None


def _frame(value: Any, where: str) -> str:
    if value not in FRAMES:
        raise InputError(f"{where}: unknown layer frame {value!r}; expected one of {', '.join(FRAMES)}")
    return str(value)


def _center(value: Any, where: str) -> str:
    if value not in CENTERS:
        raise InputError(f"{where}: unknown lobe centre {value!r}; expected one of {', '.join(CENTERS)}")
    return str(value)


def from_manifest(manifest: Mapping[str, Any]) -> Layout:
    """The :class:`Layout` of a result manifest (module docstring lists the fields used)."""
    try:
        height, width = int(manifest["height"]), int(manifest["width"])
        raw_layers = list(manifest["layers"])
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"manifest lacks height, width or layers ({exc})") from None
    layers = []
    owner: dict[int, int | None] = {}
    for i, layer in enumerate(raw_layers):
        try:
            ref = LayerRef(int(layer.get("index", i)), int(layer["p"]), int(layer["q"]))
            name = str(layer.get("name", ""))
            comp = layer.get("component")
            owner[ref.index] = int(comp) if comp is not None else _component_of(name)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"manifest layer {i} lacks p or q ({exc})") from None
        layers.append((ref, name))
    if not layers:
        raise InputError("manifest has no layers")
    for ref, _ in layers:
        if not (0 <= abs(ref.q) <= ref.p) or not 0 <= ref.index < len(layers):
            raise InputError(f"manifest layer {ref} is out of range")
    shape = (manifest.get("files") or {}).get("coefficients.bin", {}).get("shape")
    if shape is not None and list(shape) != [len(layers), height, width, 3]:
        raise InputError(f"coefficients.bin has shape {shape}, expected {[len(layers), height, width, 3]}")

    top_center = manifest.get("center") or "R"
    if manifest.get("representation") == "reflection_map":
        comps = [Component(_center(top_center, "manifest"), "map", tuple(ref for ref, _ in layers))]
        return Layout(height, width, tuple(comps))

    default_frame = _frame(manifest.get("layout") or DEFAULT_SHRM_FRAME, "manifest layout")
    by_name = {name: ref for ref, name in layers if name}
    by_index = {ref.index: ref for ref, _ in layers}
    described = manifest.get("components") or (manifest.get("orders") or {}).get("components")
    comps = []
    if isinstance(described, Sequence) and described:
        for k, comp in enumerate(described):
            where = f"manifest component {k}"
            refs: list[LayerRef] = []
            listed = comp.get("layers")
            if listed:
                for item in listed:
                    found = by_name.get(item) if isinstance(item, str) else by_index.get(int(item))
                    if found is None:
                        raise InputError(f"{where}: layer {item!r} is not in the manifest's layers")
                    refs.append(found)
            else:
                refs = [ref for ref, _ in layers if owner[ref.index] == comp.get("index", k)]
            if not refs:
                raise InputError(f"{where} has no layers")
            frame = _frame(comp.get("frame") or comp.get("layout") or default_frame, where)
            comps.append(Component(_center(comp.get("center", top_center), where), frame, tuple(refs)))
    else:
        groups: dict[int, list[LayerRef]] = {}
        for ref, _ in layers:
            groups.setdefault(owner[ref.index] or 0, []).append(ref)
        if len(groups) > 1:
            raise InputError("manifest has layers of several components but no 'components' giving their centres")
        comps = [Component(_center(top_center, "manifest"), default_frame, tuple(next(iter(groups.values()))))]
    used = [ref.index for c in comps for ref in c.layers]
    if len(set(used)) != len(used):
        raise InputError("manifest components share layers")
    return Layout(height, width, tuple(comps))


def defines(layout: Layout) -> dict[str, object]:
    """The ``#define`` tables of ``shrm.glsl`` for this layout (constants come from the manifest, STYLE.md)."""
    first, counts = [], []
    k = 0
    for c in layout.components:
        first.append(k)
        counts.append(len(c.layers))
        k += len(c.layers)
    return {
        "SH_ORDER": layout.sh_order,
        "SHRM_NUM_LAYERS": layout.num_layers,
        "SHRM_NUM_COMPONENTS": len(layout.components),
        "SHRM_MAX_LAYERS": max(counts),
        "SHRM_HAS_LOCAL": int(any(c.frame == "local" for c in layout.components)),
        "SHRM_LAYER_SH": [layer.sh_index for c in layout.components for layer in c.layers],
        "SHRM_COMPONENT_CENTER": [CENTERS[c.center] for c in layout.components],
        "SHRM_COMPONENT_FRAME": [FRAMES[c.frame] for c in layout.components],
        "SHRM_COMPONENT_FIRST": first,
        "SHRM_COMPONENT_COUNT": counts,
    }


def uniform_weights(layout: Layout, view_env: NDArray[np.floating] | Sequence[float]) -> NDArray[np.float32]:
    """``u_layer_weight`` for a distant view V (environment frame): 1 for plain maps, ``Yr_pq(V)`` for global
    maps (seed 000 eq. 12, computed once per frame), unused (0) for local maps (weighted per texel)."""
    from relight.conventions import dirs_to_angles
    from relight.shrm import real_harmonics

    v = np.asarray(view_env, dtype=np.float64)
    theta, phi = dirs_to_angles(v)
    y = real_harmonics(max(layout.sh_order, 0), theta, phi)
    out = []
    for c in layout.components:
        for layer in c.layers:
            if c.frame == "map":
                out.append(1.0)
            elif c.frame == "global":
                out.append(float(y[layer.sh_index]))
            else:
                out.append(0.0)
    return np.asarray(out, dtype=np.float32)


def layers_from_shrm(shrm: Any, *, frame: str = "local") -> tuple[dict[str, Any], NDArray[np.float32]]:
    """A manifest (the fields above) and the (layers, S, 2S, 3) stack of an in-memory ``relight.shrm.SHRM``.

    ``frame="local"`` stores each component's local maps ``Br_pq`` (``relight.shrm_io`` layout);
    ``frame="global"`` stores ``B~r_pq`` (eq. 8, ``SHRMComponent.global_maps``; all (P+1)^2 terms).
    """
    _frame(frame, "layers_from_shrm")
    layers: list[dict[str, Any]] = []
    comps: list[dict[str, Any]] = []
    stack = []
    for k, comp in enumerate(shrm.components):
        if frame == "global" and comp.P > 0:
            terms = [(p, q) for p in range(comp.P + 1) for q in range(-p, p + 1)]
            maps = comp.global_maps()
        else:
            terms, maps = list(comp.terms), comp.maps
        names = []
        for (p, q), m in zip(terms, maps, strict=True):
            name = f"c{k}.p{p}.q{q}"
            layers.append({"index": len(layers), "name": name, "p": p, "q": q})
            names.append(name)
            stack.append(np.asarray(m, dtype=np.float32))
        comps.append({"index": k, "center": comp.center, "P": comp.P, "layers": names, "frame": frame})
    manifest = {"representation": "shrm", "layout": frame, "height": shrm.height, "width": shrm.width,
                "layers": layers, "components": comps}
    return manifest, np.stack(stack)


def to_shrm(layout: Layout, coefficients: NDArray[np.floating]) -> Any:
    """A ``relight.shrm.SHRM`` holding a result's layers (manifest order, (layers, S, 2S, 3)), for CPU evaluation.

    Plain maps (``"map"``) become radial components with ``B_00 = map / Y_00`` (so ``B_00 Y_00`` is the map);
    local layers become components with their terms. Global layers have no local form here: ``InputError``.
    """
    from relight.shrm import SHRM, Y00, SHRMComponent, Structure

    comps = []
    for c in layout.components:
        maps = np.stack([np.asarray(coefficients[ref.index], dtype=np.float64) for ref in c.layers])
        if c.frame == "map":
            comps.append(SHRMComponent(c.center, "radial", 0, 0, [(0, 0)], maps / Y00, {}))
        elif c.frame == "local":
            terms = [(ref.p, ref.q) for ref in c.layers]
            structure: Structure = ("radial" if terms == [(0, 0)] else
                                    "azimuthal" if all(q == 0 for _, q in terms) else "general")
            comps.append(SHRMComponent(c.center, structure, 0, c.P, terms, maps, {}))
        else:
            raise InputError("global (eq. 8) layers cannot be turned back into a local SHRM here")
    return SHRM(comps)


def global_layers(layout: Layout, coefficients: NDArray[np.floating]) -> tuple[Layout, NDArray[np.float64]]:
    """The global form (seed 000 eq. 8) of a result, for the distant viewer's per-frame eq. 12 with constant
    weights: local components become global ones with all (P+1)^2 terms (``relight.shrm.local_to_global``);
    P = 0 local components keep their layer (``B~_00 = B_00``); plain maps and global layers are copied.
    ``coefficients`` are in manifest order; returns the new layout and its layers (texture order = index order).
    ``web/src/global.js`` is the browser's twin.
    """
    from relight.conventions import ring_thetas
    from relight.shrm import local_to_global

    comps: list[Component] = []
    stacks = []
    k = 0
    for c in layout.components:
        maps = np.stack([np.asarray(coefficients[ref.index], dtype=np.float64) for ref in c.layers])
        if c.frame != "local" or c.P == 0:
            terms = [(ref.p, ref.q) for ref in c.layers]
            frame = "global" if c.frame == "local" else c.frame
        else:
            maps = local_to_global(maps, [(ref.p, ref.q) for ref in c.layers], ring_thetas(layout.height))
            terms = [(p, q) for p in range(c.P + 1) for q in range(-p, p + 1)]
            frame = "global"
        refs = tuple(LayerRef(k + i, p, q) for i, (p, q) in enumerate(terms))
        k += len(refs)
        comps.append(Component(c.center, frame, refs))
        stacks.append(maps)
    return Layout(layout.height, layout.width, tuple(comps)), np.concatenate(stacks)
