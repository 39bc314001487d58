"""Write the JSON fixtures of the JavaScript unit tests (``node --test web/test/``) from the Python code.

``python3 tests/web/make_js_fixtures.py`` rewrites ``web/test/fixtures/*.json``; ``tests/web/test_js_units.py``
checks they are current and runs the node tests. Values come from ``relight.sh`` (the contract: the real basis of
``relight.sh.to_real``), ``relight.gl.layout`` and ``relight.gl.shaders``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight import sh  # noqa: E402
from relight.conventions import dirs_to_angles  # noqa: E402
from relight.gl import layout, shaders  # noqa: E402

FIXTURES = REPO / "web" / "test" / "fixtures"
SH_ORDER = 8


def sh_directions() -> np.ndarray:
    rng = np.random.default_rng(42)
    d = rng.normal(size=(40, 3))
    extra = np.array([[0, 1, 0], [0, -1, 0], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1], [1, 1e-9, 0]], float)
    d = np.concatenate([d, extra])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def real_basis(order: int, dirs: np.ndarray) -> np.ndarray:
    """Yr_k(d) for every real index k: evaluate ``from_real(e_k)`` with relight.sh (to_real's basis)."""
    theta, phi = dirs_to_angles(dirs)
    n = (order + 1) ** 2
    out = np.zeros((dirs.shape[0], n))
    for k in range(n):
        e = np.zeros(n)
        e[k] = 1.0
        out[:, k] = sh.evaluate(sh.from_real(e, order), order, theta, phi)
    return out


def sh_fixture() -> dict[str, Any]:
    dirs = sh_directions()
    return {"source": "relight.sh.evaluate(relight.sh.from_real(e_k))", "order": SH_ORDER,
            "directions": dirs.tolist(), "values": real_basis(SH_ORDER, dirs).tolist()}


def manifests() -> dict[str, dict[str, Any]]:
    """Manifests of every shape the viewer meets: worker reflection maps, relight.shrm_io SHRMs, service layers."""
    def terms(p_order: int) -> list[tuple[int, int]]:
        return [(p, q) for p in range(p_order + 1) for q in range(-p, p + 1)]

    def layers(names: list[tuple[str, int, int]]) -> list[dict[str, Any]]:
        return [{"index": i, "name": n, "p": p, "q": q} for i, (n, p, q) in enumerate(names)]

    shrm_names = [(f"c0.p{p}.q{q}", p, q) for p, q in terms(2)] + [("c1.p0.q0", 0, 0)] + [
        (f"c2.p{p}.q0", p, 0) for p in range(3)]
    sum_names = [("c0.p0.q0", 0, 0)] + [(f"c1.p{p}.q{q}", p, q) for p, q in terms(1)]
    shuffled = [shrm_names[i] for i in np.random.default_rng(1).permutation(len(shrm_names))]
    return {
        "reflection_map_N": {"representation": "reflection_map", "center": "N", "height": 8, "width": 16,
                             "layers": layers([("", 0, 0)]),
                             "files": {"coefficients.bin": {"shape": [1, 8, 16, 3], "dtype": "float16"}}},
        "shrm_components": {"representation": "shrm", "layout": "local", "height": 8, "width": 16,
                            "layers": layers(shuffled),
                            "components": [{"index": 0, "center": "R", "P": 2,
                                            "layers": [n for n, _, _ in shrm_names[:9]]},
                                           {"index": 1, "center": "N", "P": 0},
                                           {"index": 2, "center": "T", "P": 2, "frame": "global"}]},
        "service_sum_of_lobes": {"representation": "shrm", "center": None, "height": 8, "width": 16,
                                 "layers": [dict(layer, component=int(layer["name"][1])) for layer in
                                            layers(sum_names)],
                                 "orders": {"F_B": 8, "P_B": 1, "components": [
                                     {"center": "N", "structure": "radial", "F_B": 8, "P_B": 0, "maps": 1},
                                     {"center": "R", "structure": "general", "F_B": 8, "P_B": 1, "maps": 4}]}},
        "shrm_single_global": {"representation": "shrm", "layout": "global", "center": "R", "height": 8,
                               "width": 16, "layers": layers([(f"c0.p{p}.q{q}", p, q) for p, q in terms(3)])},
    }


def layout_fixture() -> dict[str, Any]:
    view = np.array([0.3, 0.8, -0.5]) / np.linalg.norm([0.3, 0.8, -0.5])
    cases = {}
    for name, man in manifests().items():
        lay = layout.from_manifest(man)
        cases[name] = {
            "manifest": man,
            "texture_order": lay.texture_order,
            "defines": [[k, v] for k, v in layout.defines(lay).items()],
            "weights": layout.uniform_weights(lay, view).astype(float).tolist(),
            "components": [{"center": c.center, "frame": c.frame, "P": c.P,
                            "layers": [[r.index, r.p, r.q] for r in c.layers]} for c in lay.components],
        }
    bad = {
        "two_components_without_centres": {"representation": "shrm", "height": 8, "width": 16,
                                           "layers": [{"index": 0, "name": "c0.p0.q0", "p": 0, "q": 0},
                                                      {"index": 1, "name": "c1.p0.q0", "p": 0, "q": 0}]},
        "unknown_frame": {"representation": "shrm", "layout": "sideways", "height": 8, "width": 16,
                          "layers": [{"index": 0, "name": "", "p": 0, "q": 0}]},
        "wrong_shape": {"representation": "shrm", "height": 8, "width": 16,
                        "layers": [{"index": 0, "name": "", "p": 0, "q": 0}],
                        "files": {"coefficients.bin": {"shape": [1, 8, 8, 3]}}},
    }
    for man in bad.values():
        try:
            layout.from_manifest(man)
        except ValueError:
            continue
        raise AssertionError(f"relight.gl.layout accepted a bad manifest: {man}")
    return {"view": view.tolist(), "cases": cases, "bad": bad}


def shader_fixture() -> dict[str, Any]:
    lay = layout.from_manifest(manifests()["shrm_components"])
    defs = layout.defines(lay)
    builds = []
    for name, extra in (("object.frag.glsl", {"SHADING_LOCAL": None, "OBJECT_SPHERE": None}),
                        ("object.frag.glsl", {"SHADING_VIEW_MAP": None}),
                        ("view_map.frag.glsl", {}), ("background.frag.glsl", {}), ("object.vert.glsl", {})):
        d = {**defs, **extra} if name != "background.frag.glsl" and name != "object.vert.glsl" else extra
        builds.append({"name": name, "defines": [[k, v] for k, v in d.items()],  # ordered (JSON sorts keys)
                       "text": shaders.build(name, target="300 es", defines=d)})
    gaussian = {"GAUSSIAN_K": 3, "GAUSSIAN_ROWS": 57, "GAUSSIAN_GRID": None, "GAUSSIAN_LEVELS": 12,
                "GAUSSIAN_VISIBILITY": None, "VIS_MODE": 3, "SH_ORDER": 3, "OUTPUT_LINEAR": None}
    searched = {"GAUSSIAN_K": 5, "GAUSSIAN_ROWS": 9, "GAUSSIAN_SEARCH_STEP": 4, "GAUSSIAN_LEVELS": 4,
                "GAUSSIAN_SPHERE": None, "OUTPUT_LINEAR": None}
    for name, d in (("gaussian.frag.glsl", gaussian), ("gaussian.vert.glsl", gaussian),
                    ("gaussian.frag.glsl", searched)):
        builds.append({"name": name, "defines": [[k, v] for k, v in d.items()],
                       "text": shaders.build(name, target="300 es", defines=d)})
    files = {}
    for path in sorted(shaders.SHADER_DIR.rglob("*.glsl")):
        rel = path.relative_to(shaders.SHADER_DIR).as_posix()
        files[rel] = path.read_text(encoding="utf-8")
    return {"files": files, "builds": builds}


def global_fixture() -> dict[str, Any]:
    """Local layers (values exact in float16) and their global form from relight.gl.layout.global_layers."""
    rng = np.random.default_rng(11)
    rows = 6
    names = [(f"c0.p{p}.q{q}", p, q) for p in range(3) for q in range(-p, p + 1)] + [("c1.p0.q0", 0, 0)] + [
        (f"c2.p{p}.q0", p, 0) for p in range(4)]
    manifest = {"representation": "shrm", "height": rows, "width": 2 * rows,
                "layers": [{"index": i, "name": n, "p": p, "q": q} for i, (n, p, q) in enumerate(names)],
                "components": [{"center": "R"}, {"center": "N"}, {"center": "T"}]}
    local = np.round(rng.normal(size=(len(names), rows, 2 * rows, 3)) * 64.0) / 64.0  # exact binary16 values
    lay = layout.from_manifest(manifest)
    glay, maps = layout.global_layers(lay, local)
    return {"manifest": manifest, "local": local.ravel().tolist(), "global": maps.ravel().tolist(),
            "components": [{"center": c.center, "frame": c.frame, "P": c.P,
                            "layers": [[r.p, r.q] for r in c.layers]} for c in glay.components],
            "wigner": {"beta": 0.7, "p": 3, "d": _wigner(3, 0.7)}}


def _wigner(p: int, beta: float) -> list[float]:
    from relight import wigner

    return [float(x) for x in wigner.wigner_d_matrix(p, np.array([beta]))[0].ravel()]


def _lobe_case(rng: np.random.Generator, k: int, elevations: list[float]) -> dict[str, Any]:
    from relight.brdf.gaussian_lobes import GaussianLobes
    from relight.gl.gaussian import LobeTable

    n = len(elevations)
    half = np.float16
    mu = rng.uniform(-1.5, 1.5, (n, k)).astype(half)
    sigma = rng.uniform(0.02, 1.0, (n, k)).astype(half)
    weight = rng.uniform(0.0, 2.0, (n, k, 3)).astype(half)
    weight[rng.random((n, k)) < 0.2] = 0.0  # dead lobes
    table = LobeTable(GaussianLobes(np.array(elevations), mu.astype(np.float64), sigma.astype(np.float64),
                                    weight.astype(np.float64)))
    shape = np.zeros((n, k, 4), dtype=half)
    shape[..., 0], shape[..., 1] = mu, sigma
    w4 = np.zeros((n, k, 4), dtype=half)
    w4[..., :3] = weight
    return {"lobes": k, "elevations": elevations, "shape": [int(x) for x in shape.view(np.uint16).ravel()],
            "weight": [int(x) for x in w4.view(np.uint16).ravel()], "rows": table.rows,
            "grid": None if table.grid is None else list(table.grid), "defines": table.defines(),
            "words": [int(x) for x in table.words().ravel()]}


def gaussian_fixture() -> dict[str, Any]:
    """relight.gl.gaussian.LobeTable of materials given as float16 bits: gaussian.js's lobeTable must give the same
    rows, grid, defines and words. Cases: a fit's grid (even elevations, then bisections), an even grid coarser than
    the elevations' gap, elevations on no grid (the bisection path), one elevation, two, and K from 1 to 8."""
    rng = np.random.default_rng(17)
    step = 1.5 / 4
    fit_like = sorted({*(step * np.arange(5)), step * 1.5, step * 1.75, step * 2.5})
    uneven = [0.0, 0.1234567, 0.5, 0.61, 1.3]
    cases = [_lobe_case(rng, 3, [float(x) for x in fit_like]), _lobe_case(rng, 1, [0.0, 0.3, 0.55, 1.2]),
             _lobe_case(rng, 5, uneven), _lobe_case(rng, 8, [0.4]), _lobe_case(rng, 2, [0.0, 1.4]),
             _lobe_case(rng, 4, [0.0, 0.01, 1.5])]
    return {"cases": cases}


def fixtures() -> dict[str, str]:
    return {name: json.dumps(data, indent=1, sort_keys=True) + "\n" for name, data in (
        ("sh.json", sh_fixture()), ("layout.json", layout_fixture()), ("shaders.json", shader_fixture()),
        ("global.json", global_fixture()), ("gaussian.json", gaussian_fixture()))}


def main() -> None:
    FIXTURES.mkdir(parents=True, exist_ok=True)
    for name, text in fixtures().items():
        (FIXTURES / name).write_text(text, encoding="utf-8")
        print("wrote", FIXTURES / name)


if __name__ == "__main__":
    main()
