"""``/brdfs``: strict validation (422 naming the field), content-addressed ids, measured MERL files."""

from __future__ import annotations

import struct
from typing import Any

import httpx
import pytest

from .support import assert_healthy, assert_problem

pytestmark = pytest.mark.timeout(60)


def test_create_and_get(http: httpx.Client) -> None:
    r = http.post("/brdfs", json={"kind": "phong", "s": 32})
    assert r.status_code in (200, 201), r.text
    body = r.json()
    assert body["kind"] == "phong" and body["radially_symmetric"] is True and body["center"] == "R"
    again = http.post("/brdfs", json={"kind": "phong", "s": 32.0})
    assert again.status_code == 200 and again.json()["id"] == body["id"]
    assert http.get(f"/brdfs/{body['id']}").json()["spec"] == body["spec"]


@pytest.mark.parametrize(("spec", "field"), [
    ({"kind": "phong", "s": -1}, "s"),
    ({"kind": "phong", "s": "NaN"}, "s"),
    ({"kind": "phong", "s": 32, "shininess": 3}, "shininess"),
    ({"kind": "no-such-model"}, "kind"),
    ({"s": 3}, "kind"),
])
def test_invalid_specs_name_the_field(http: httpx.Client, spec: dict[str, Any], field: str) -> None:
    body = assert_problem(http.post("/brdfs", json=spec), 422)
    assert field in body["detail"], body
    assert any(field in e["field"] or field in e["message"] for e in body["errors"]), body
    assert_healthy(http)


def test_nan_literal_rejected(http: httpx.Client) -> None:
    r = http.post("/brdfs", content=b'{"kind": "phong", "s": NaN}', headers={"Content-Type": "application/json"})
    assert r.status_code == 422 and r.headers["content-type"].startswith("application/problem+json")


def test_measured_merl_validation(http: httpx.Client) -> None:
    bad_dims = struct.pack("<3i", 90, 90, 90) + bytes(64)
    assert_problem(http.post("/brdfs/measured", content=bad_dims), 422, "(90, 90, 180)")
    short = struct.pack("<3i", 90, 90, 180) + bytes(800)
    assert_problem(http.post("/brdfs/measured", content=short), 422, str(12 + 8 * 3 * 90 * 90 * 180))
    assert_problem(http.post("/brdfs/measured", content=b""), 422)
    assert_healthy(http)


def test_unknown_brdf_id(http: httpx.Client) -> None:
    assert_problem(http.get("/brdfs/" + "a" * 64), 404, "a" * 64)


EXAMPLES: list[dict[str, Any]] = [
    {"kind": "phong", "s": 32},
    {"kind": "lambert", "albedo": [0.8, 0.6, 0.4]},
    {"kind": "lobe1d", "t": [0.0, 0.5, 1.0], "u": [0.0, 0.2, 1.0], "center": "N"},
    {"kind": "microfacet", "sigma": 0.3},
    {"kind": "torrance-sparrow", "alpha": 0.2, "fresnel": "conductor", "eta": [0.2, 0.9, 1.1], "k": 3.0},
    {"kind": "ggx", "alpha": 0.25, "fresnel": "schlick", "f0": 0.04},
    {"kind": "blinn-phong", "s": 50},
    {"kind": "lafortune", "lobes": [[-0.8, 0.9, 20.0]], "diffuse": 0.3},
    {"kind": "ward", "rho_d": 0.3, "rho_s": 0.1, "alpha": 0.15},
    {"kind": "oren-nayar", "sigma": 0.4, "albedo": 0.7},
    {"kind": "kajiya-kay", "s": 20},
    {"kind": "ggx-ld", "roughness": 0.3},
    {"kind": "gltf-pbr", "base": [0.9, 0.6, 0.2], "metallic": 0.5, "roughness": 0.4},
    {"kind": "sum", "lobes": [{"kind": "lambert", "albedo": 0.5}, {"kind": "phong", "s": 64}]},
]


def test_union_covers_every_core_model() -> None:
    import inspect

    from relight.brdf import models, splitsum
    from relight.brdf.spec import VALID_KINDS
    from relight.contract.brdfs import KINDS, PRESETS, SPLITSUM_MIN_ROUGHNESS

    home = {models.__name__, "relight.brdf.radial", "relight.brdf.microfacet"}  # re-exported by models
    classes = [cls for _, cls in inspect.getmembers(models, inspect.isclass) if cls.__module__ in home]
    core = {str(getattr(cls, "kind", "")) for cls in classes} - {""}
    core |= {splitsum.GGXSplitSum.kind}  # the engines' split-sum lobe (issue 17)
    assert set(PRESETS) <= set(VALID_KINDS)  # presets are core spec kinds that expand into a sum
    assert core | set(PRESETS) == set(KINDS), f"service union {sorted(KINDS)} vs core models {sorted(core)}"
    assert SPLITSUM_MIN_ROUGHNESS == splitsum.MIN_ROUGHNESS
    assert {e["kind"] for e in EXAMPLES} == set(KINDS)


@pytest.mark.parametrize("spec", EXAMPLES, ids=[e["kind"] for e in EXAMPLES])
def test_every_model_registers(http: httpx.Client, spec: dict[str, Any]) -> None:
    r = http.post("/brdfs", json=spec)
    assert r.status_code in (200, 201), r.text
    body = r.json()
    assert body["kind"] == ("sum" if spec["kind"] == "gltf-pbr" else spec["kind"])  # a preset is stored as its sum
    assert http.get(f"/brdfs/{body['id']}").json()["id"] == body["id"]


def test_gltf_pbr_preset_is_its_sum(http: httpx.Client) -> None:
    """The preset is stored as the sum it expands to (glTF 2.0 App. B: c_diff = base (1 - m), F0 = 0.04 (1 - m) +
    base m, alpha = r^2; worked by hand for base 0.5, m = 0.5, r = 0.4), which the union also takes as a sum."""
    preset = http.post("/brdfs", json={"kind": "gltf-pbr", "base": 0.5, "metallic": 0.5, "roughness": 0.4}).json()
    string = http.post("/brdfs", json={"kind": "sum", "lobes": [{"kind": "lambert", "albedo": 0.25},
                                                                {"kind": "ggx", "alpha": 0.16, "fresnel": "schlick",
                                                                 "f0": 0.27}]})
    assert string.status_code in (200, 201), string.text
    assert preset["spec"]["lobes"][1]["alpha"] == pytest.approx(0.16)
    assert preset["spec"]["lobes"][1]["f0"] == pytest.approx(0.27)
    assert preset["spec"]["lobes"][0]["albedo"] == pytest.approx(0.25)
    # a roughness whose alpha = r^2 is below the service's MIN_ROUGHNESS is named
    body = assert_problem(http.post("/brdfs", json={"kind": "gltf-pbr", "roughness": 0.05}), 422)
    assert "roughness" in body["detail"], body


@pytest.mark.parametrize("spec", ["merl:/etc/hosts", "lobe1d:/tmp/lobe.json", "/etc/relight/spec.json",
                                  "lambert+measured:/tmp/table.npz", "MERL:gold.binary"])
def test_specs_naming_server_files_are_refused(http: httpx.Client, sample_exr: bytes, spec: str) -> None:
    env = http.post("/envmaps", content=sample_exr).json()
    body = assert_problem(http.post("/plan", json={"envmap": env["id"], "brdf": spec}), 422, "brdf")
    assert "not accepted" in body["detail"]
    assert_problem(http.post("/brdfs", json={"kind": "lobe1d", "path": "/etc/hosts"}), 422, "path")
