"""The shape list: the objects a prefiltered material can be shown on, written once.

``"sphere"`` is the analytic unit sphere (the paper's test object, seed 000 §7.5); the others are the sample meshes
of ``data/meshes`` (``bunny.obj``: the Stanford bunny; ``teapot.obj``: the Utah teapot). The viewer
(``relight.gl.mesh``), the scene schema (``relight.planning.scene``) and the API's ``object`` / ``shape``
parameters accept exactly these names.
"""

from __future__ import annotations

from typing import Final, Literal, get_args

#: A shape name, as a type (for pydantic models and signatures).
Shape = Literal["sphere", "bunny", "teapot"]
#: Every shape, in the order the viewer lists them.
SHAPES: Final[tuple[str, ...]] = get_args(Shape)
#: The shapes drawn from a mesh file of ``data/meshes`` (all but the analytic sphere).
SAMPLE_MESHES: Final[tuple[str, ...]] = tuple(s for s in SHAPES if s != "sphere")
