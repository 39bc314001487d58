"""Tests for relight.shapes, the one shape list: every module that names shapes uses it, and every sample mesh
has its file."""

from __future__ import annotations

from pathlib import Path

from relight import shapes
from relight.gl import mesh as gl_mesh
from relight.planning import scene

MESHES = Path(__file__).resolve().parents[2] / "data" / "meshes"


def test_one_list_everywhere() -> None:
    assert shapes.SHAPES == ("sphere", "bunny", "teapot")
    assert gl_mesh.OBJECTS is shapes.SHAPES
    assert scene.SHAPES is shapes.SHAPES
    assert shapes.SAMPLE_MESHES == ("bunny", "teapot")


def test_every_sample_mesh_has_a_file() -> None:
    for name in shapes.SAMPLE_MESHES:
        assert (MESHES / f"{name}.obj").is_file(), name
