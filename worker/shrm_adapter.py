"""The SHRM path of a job (``relight.shrm.create_shrm``) and view evaluation (``relight.shrm.reflect``, eq. 12).

Result files follow ``relight.shrm_io``: layers ``c<k>.p<p>.q<q>`` and the manifest in the EXR attribute
``relight.shrm``, so ``relight.shrm_io.read_shrm`` reads a downloaded ``coefficients.exr`` directly. Values that
change from run to run (timings, cache hits) are left out of the files so that a recomputed result is
byte-identical.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.worker.progress import Reporter
from relight.worker.results import Layer, strip_volatile


def shrm_layers(shrm: Any) -> list[Layer]:
    """The texture layers of an SHRM (``relight.shrm.SHRM``): one ``c<k>.p<p>.q<q>`` layer per map, components in
    order."""
    from relight.shrm_io import layer_name

    return [
        Layer(name=layer_name(k, p, q), p=p, q=q, pixels=np.asarray(m, dtype=np.float32), component=k)
        for k, comp in enumerate(shrm.components)
        for (p, q), m in zip(comp.terms, comp.maps, strict=True)
    ]


def prefilter(
    pixels: NDArray[np.float32], brdf: Any, params: dict[str, Any], report: Reporter
) -> tuple[list[Layer], str, dict[str, Any], dict[str, str]]:
    """Run ``create_shrm`` and return (layers, representation, report, EXR attributes)."""
    from relight.shrm import create_shrm
    from relight.shrm_io import ATTRIBUTE, manifest

    order = params.get("order")
    shrm = create_shrm(pixels, brdf, epsilon=params.get("epsilon") if order is None else None, order=order,
                       p_order=params.get("p_order"), size=params.get("size"))
    report("writing", 0.9)
    layers = shrm_layers(shrm)
    man = strip_volatile(manifest(shrm))
    typed = shrm.typed_report
    predicted = typed.predicted
    comps = shrm.components
    f_l = typed.components[0].orders.get("F_L")
    orders = {
        "F_B": max(c.F for c in comps), "P_B": max(c.P for c in comps), "F_L": f_l,
        "rms_min_of_errors": predicted.rms_min_of_errors, "rms_appendix_b": predicted.rms_appendix_b,
        "components": [{"center": c.center, "structure": c.structure, "F_B": c.F, "P_B": c.P,
                        "maps": len(c.terms)} for c in comps],
    }
    core_report = {**typed.to_json(), "orders": orders, "center": comps[0].center if len(comps) == 1 else None}
    return layers, "shrm", core_report, {ATTRIBUTE: json.dumps(man, sort_keys=True)}


def reflect(exr_path: str, view: NDArray[np.float64]) -> NDArray[np.float64]:
    """The eq. 12 reflection map of a stored SHRM for the distant view ``view``."""
    from relight.shrm import reflect as core_reflect
    from relight.shrm_io import read_shrm

    return np.asarray(core_reflect(read_shrm(exr_path), view), dtype=np.float64)


def reflect_radial(image: NDArray[np.float64], center: str, f_b: int, lobe: dict[str, Any],
                   view: NDArray[np.float64]) -> NDArray[np.float64]:
    """A stored reflection map (one radial lobe) seen from ``view``: the map itself for an R-centred lobe; for an
    N-centred one (Lambert) the core's lookup at N = normalize(R + V)."""
    if center == "R":
        return image
    from relight.shrm import SHRM, Y00, SHRMComponent
    from relight.shrm import reflect as core_reflect

    comp = SHRMComponent(center=center, structure="radial", F=f_b, P=0, terms=[(0, 0)],
                         maps=(image / Y00)[None], lobe=lobe)
    return np.asarray(core_reflect(SHRM(components=[comp]), view), dtype=np.float64)
