"""SHRM files: layered EXR + JSON manifest round trip (relight.shrm_io)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from relight.envmap import read_exr_layers, write_exr_layers
from relight.errors import InputError
from relight.shrm import SHRM, SHRMComponent, reflect, terms_for
from relight.shrm_io import ATTRIBUTE, layer_name, read_shrm, sidecar_path, write_shrm


def _shrm(rng: np.random.Generator, s: int = 8) -> SHRM:
    comps = []
    for center, structure, p_order in (("R", "general", 2), ("N", "radial", 0), ("T", "azimuthal", 3)):
        terms = terms_for(structure, p_order)  # type: ignore[arg-type]
        maps = rng.standard_normal((len(terms), s, 2 * s, 3)) * 10.0 ** rng.uniform(-3, 3)
        comps.append(
            SHRMComponent(center=center, structure=structure, F=7, P=p_order, terms=terms, maps=maps,  # type: ignore[arg-type]
                          lobe={"kind": f"test-{structure}"}, report={"orders": {"F_B": 7, "P_B": p_order}})
        )
    return SHRM(components=comps, brdf={"kind": "sum", "n": 3},
                report={"relight_version": "x", "predicted": {"rms_brdf": 0.1}, "timings": {"synthesis": 0.01}})


def test_round_trip_is_exact_in_float32(tmp_path: Path) -> None:
    rng = np.random.default_rng(42)
    src = _shrm(rng)
    path = tmp_path / "a.exr"
    man = write_shrm(path, src)
    assert sidecar_path(path).exists()
    back = read_shrm(path)
    assert [c.center for c in back.components] == ["R", "N", "T"]
    assert [c.structure for c in back.components] == ["general", "radial", "azimuthal"]
    for a, b in zip(src.components, back.components, strict=True):
        assert a.terms == b.terms and a.F == b.F and a.P == b.P and a.lobe == b.lobe
        np.testing.assert_array_equal(b.maps, a.maps.astype(np.float32).astype(np.float64))
    # the manifest is in the EXR header and the sidecar, identical
    _, attrs = read_exr_layers(str(path))
    assert json.loads(attrs[ATTRIBUTE]) == json.loads(sidecar_path(path).read_text()) == man
    # writing what was read reproduces the same file content
    path2 = tmp_path / "b.exr"
    man2 = write_shrm(path2, back)
    assert man2 == man
    again = read_shrm(path2)
    for a, b in zip(back.components, again.components, strict=True):
        np.testing.assert_array_equal(a.maps, b.maps)
    # layer names carry component, p and q
    layers, _ = read_exr_layers(str(path))
    assert layer_name(0, 2, -1) in layers and layer_name(2, 3, 0) in layers and "c1.p0.q0" in layers
    assert len(layers) == 9 + 1 + 4


def test_half_storage_is_close(tmp_path: Path) -> None:
    src = _shrm(np.random.default_rng(1))
    for c in src.components:
        c.maps = np.clip(c.maps, -6e4, 6e4)
    write_shrm(tmp_path / "h.exr", src, half=True)
    back = read_shrm(tmp_path / "h.exr")
    for a, b in zip(src.components, back.components, strict=True):
        np.testing.assert_allclose(b.maps, a.maps, rtol=1e-3, atol=6e-8)  # half: 11-bit mantissa, subnormals below 6e-5


def test_read_falls_back_to_sidecar(tmp_path: Path) -> None:
    src = _shrm(np.random.default_rng(2))
    path = tmp_path / "s.exr"
    write_shrm(path, src)
    layers, _ = read_exr_layers(str(path))
    write_exr_layers(path, layers)  # same layers, no manifest attribute
    back = read_shrm(path)
    assert len(back.components) == 3
    sidecar_path(path).unlink()
    with pytest.raises(InputError, match="no SHRM manifest"):
        read_shrm(path)


def test_malformed_files_raise_input_error(tmp_path: Path) -> None:
    src = _shrm(np.random.default_rng(3))
    path = tmp_path / "m.exr"
    write_shrm(path, src)
    layers, attrs = read_exr_layers(str(path))
    man = json.loads(attrs[ATTRIBUTE])

    def rewrite(m: object, lay: dict[str, np.ndarray] | None = None) -> None:
        write_exr_layers(path, lay or layers, attributes={ATTRIBUTE: m if isinstance(m, str) else json.dumps(m)})

    rewrite("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        read_shrm(path)
    rewrite({**man, "format": "other"})
    with pytest.raises(InputError, match="not a relight SHRM"):
        read_shrm(path)
    rewrite({**man, "format_version": 99})
    with pytest.raises(InputError, match="version"):
        read_shrm(path)
    broken = json.loads(json.dumps(man))
    broken["components"][0]["terms"] = [[0, 0]]
    rewrite(broken)
    with pytest.raises(InputError, match="terms do not match"):
        read_shrm(path)
    rewrite(man, {k: v for k, v in layers.items() if k != "c0.p1.q1"})
    with pytest.raises(InputError, match="missing"):
        read_shrm(path)
    del broken["components"]
    rewrite(broken)
    with pytest.raises(InputError, match="malformed"):
        read_shrm(path)


def test_read_shrm_then_reflect(tmp_path: Path) -> None:
    # a file read back evaluates identically (float32 storage) to the in-memory SHRM
    src = _shrm(np.random.default_rng(4))
    for c in src.components:
        c.maps = c.maps.astype(np.float32).astype(np.float64)
    write_shrm(tmp_path / "r.exr", src)
    back = read_shrm(tmp_path / "r.exr")
    v = np.array([0.3, -0.5, 0.8])
    np.testing.assert_array_equal(reflect(back, v), reflect(src, v))
