"""The sweep's comparison with Mitsuba 3 (``relight.tradeoff`` module docstring, "Against Mitsuba 3";
``relight.mitsuba_twin``): whether the material has a twin the map can be shown to, and each point's error against
Mitsuba's sphere image and against the reference's."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError, RelightError
from relight.mitsuba_compare import TwinSettings
from relight.tradeoff.points import is_reflection_map
from relight.tradeoff.report import Grid, MitsubaComparison

FloatArray = NDArray[np.float64]


def mitsuba_plan(brdf: Any, px: FloatArray, mitsuba: bool | None) -> tuple[dict[str, Any] | None, str | None]:
    """The Mitsuba twin to render against, or None and why not; ``mitsuba=True`` turns every why-not into an error
    (InputError for the material or the map, RelightError when Mitsuba cannot run here)."""
    from relight import mitsuba_twin

    if mitsuba is False:
        return None, "switched off (mitsuba=False, --mitsuba off)"
    bsdf = mitsuba_twin.twin(brdf)
    why: str | None = None
    if bsdf is None:
        kind = getattr(brdf, "kind", type(brdf).__name__)
        why = (f"{kind} has no Mitsuba 3 twin (relight.mitsuba_twin.twin: Torrance-Sparrow with fresnel='none' and "
               "Lambert only)")
    else:
        why = mitsuba_twin.check_bitmap_shape(px.shape)
    if why is not None and mitsuba:
        raise InputError(f"mitsuba=True (--mitsuba on): {why}")
    if why is None:
        why = mitsuba_twin.unavailable_reason()
        if why is not None and mitsuba:
            raise RelightError(f"mitsuba=True (--mitsuba on): {why}")
    return (bsdf, None) if why is None else (None, why)


def mitsuba_errors(
    px: FloatArray, brdf: Any, bsdf: dict[str, Any], view: FloatArray, ref: FloatArray, maps: list[FloatArray],
    settings: TwinSettings,
) -> tuple[list[tuple[float, float]], MitsubaComparison]:
    """Each map's relative RMS against Mitsuba's sphere image (one render) and against the reference's, and the meta
    entry (module docstring)."""
    from relight import mitsuba_compare

    center = str(brdf.center) if is_reflection_map(brdf) else "R"  # view maps are indexed by R (reflect, reference)
    t0 = time.perf_counter()
    cmp = mitsuba_compare.compare_sphere(px, bsdf, view, settings)
    render_seconds = time.perf_counter() - t0
    ref_blocks = cmp.blocks(ref, center)
    errors = []
    for m in maps:
        y = cmp.blocks(m, center)
        errors.append((mitsuba_compare.block_rms(y, cmp.truth), mitsuba_compare.block_rms(y, ref_blocks)))
    meta = MitsubaComparison(
        computed=True,
        variant=cmp.render.variant,
        bsdf=bsdf,
        view=(float(view[0]), float(view[1]), float(view[2])),
        image=Grid(height=settings.size, width=settings.size),
        spp=settings.spp,
        seed=settings.seed,
        block=settings.block,
        radius=settings.radius,
        max_angle_nv_deg=math.degrees(math.asin(settings.radius)),
        blocks=int(cmp.truth.size),
        supersample=settings.supersample,
        texels_per_pixel=cmp.texels,
        map_center=center,
        seconds=render_seconds,
        noise=cmp.noise,
        reference_error=mitsuba_compare.block_rms(ref_blocks, cmp.truth),
        metric=(f"relative RMS over the {cmp.truth.size} blocks of {settings.block} x {settings.block} pixels lying "
                f"within image radius {settings.radius:g} of a {settings.size} x {settings.size} orthographic "
                "sphere image, Rec. 709 luminance; relight's map looked up bilinearly at its centre direction, "
                f"{settings.supersample} x {settings.supersample} samples per pixel"),
    )
    return errors, meta

