"""Writing a sweep: ``tradeoff.json``, ``tradeoff_meta.json`` and three PNG plots.

Plotting needs matplotlib, an optional dependency (the ``plots`` extra; ``dev`` includes it): it is imported only
inside :func:`plot`, so the sweep itself, the service and every non-plot path run without it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from relight.errors import RelightError
from relight.jsonable import jsonable
from relight.tradeoff.sweeps import Tradeoff


def write_tradeoff(result: Tradeoff, out_dir: str | Path, *, title: str | None = None) -> dict[str, Path]:
    """``tradeoff.json`` (the list of points), ``tradeoff_meta.json`` and the three plots of :func:`plot`."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"tradeoff.json": out / "tradeoff.json", "tradeoff_meta.json": out / "tradeoff_meta.json"}
    points = [p.to_json() for p in result.points]
    paths["tradeoff.json"].write_text(json.dumps(jsonable(points), indent=1, allow_nan=False))
    paths["tradeoff_meta.json"].write_text(json.dumps(jsonable(result.meta.to_json()), indent=1, allow_nan=False))
    paths.update(plot(result, out, title=title))
    return paths


_STYLE = {"frequency": ("tab:blue", "o"), "angular": ("tab:orange", "s")}


def plot(result: Tradeoff, out_dir: str | Path, *, title: str | None = None) -> dict[str, Path]:
    """PNG plots (matplotlib, Agg): error vs time with both Pareto fronts, predicted vs measured error, predicted
    vs measured time. When the sweep measured against Mitsuba 3 (``meta.mitsuba.computed``), the frequency
    points' ``mitsuba_error`` appear as hollow markers of the same colour in the first two, with the noise floor
    (dotted) and the reference's own error against Mitsuba (dash-dotted) in the first."""
    try:
        import matplotlib
    except ImportError:
        raise RelightError("plotting needs matplotlib: pip install 'relight[plots]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    brdf = result.meta.brdf
    name = title or str(brdf.get("kind", "tradeoff") if isinstance(brdf, dict) else "tradeoff")
    paths: dict[str, Path] = {}
    pts: list[dict[str, Any]] = [p.to_json() for p in result.points]

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for method, (colour, marker) in _STYLE.items():
        mp = [p for p in pts if p["method"] == method]
        if not mp:
            continue
        ax.scatter([p["measured_seconds"] for p in mp], [max(p["measured_error"], 1e-12) for p in mp], c=colour,
                   marker=marker, label=f"{method} method", zorder=3)
        front = sorted((p for p in mp if p.get("pareto")), key=lambda p: p["measured_seconds"])
        if front:
            ax.step([p["measured_seconds"] for p in front], [max(p["measured_error"], 1e-12) for p in front],
                    where="post", color=colour, alpha=0.6, label=f"{method} Pareto front")
        for p in mp:
            lab = (f"F={p['orders'].get('F_B')}" + (f",P={p['orders'].get('P_B')}" if p["orders"].get("P_B") else "")
                   if method == "frequency" else f"t={p['setting']['truncation']:g}")
            ax.annotate(lab, (p["measured_seconds"], max(p["measured_error"], 1e-12)), fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
    mits = result.meta.mitsuba
    if mits.computed and mits.noise is not None and mits.reference_error is not None:
        colour, marker = _STYLE["frequency"]
        mp = [p for p in pts if p["method"] == "frequency" and p.get("mitsuba_error") is not None]
        if mp:
            ax.scatter([p["measured_seconds"] for p in mp], [max(float(p["mitsuba_error"]), 1e-12) for p in mp],
                       facecolors="none", edgecolors=colour, marker=marker, label="frequency vs Mitsuba 3", zorder=3)
        ax.axhline(max(mits.noise, 1e-12), color="0.35", ls=":", lw=1.0,
                   label="Mitsuba 3 noise floor")
        ax.axhline(max(mits.reference_error, 1e-12), color="0.35", ls="-.", lw=0.8,
                   label="angular reference vs Mitsuba 3")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("measured seconds")
    ax.set_ylabel("measured relative RMS error")
    ax.set_title(f"{name}\naccuracy against time", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    paths["error_vs_time.png"] = out / "error_vs_time.png"
    fig.savefig(paths["error_vs_time.png"], dpi=110)
    plt.close(fig)

    for key, pred_key, meas_key, label in (
        ("predicted_vs_measured_error.png", "predicted_error", "measured_error", "relative RMS error"),
        ("predicted_vs_measured_time.png", "predicted_seconds", "measured_seconds", "seconds"),
    ):
        fig, ax = plt.subplots(figsize=(5.2, 4.6))
        vals: list[float] = []
        for method, (colour, marker) in _STYLE.items():
            mp = [p for p in pts if p["method"] == method and p.get(pred_key) and p.get(meas_key)]
            if not mp:
                continue
            x = [max(float(p[pred_key]), 1e-12) for p in mp]
            y = [max(float(p[meas_key]), 1e-12) for p in mp]
            vals += x + y
            ax.scatter(x, y, c=colour, marker=marker, label=f"{method} method", zorder=3)
            if pred_key == "predicted_error" and method == "frequency":
                b = [(max(float(p["predicted_error_bound"]), 1e-12), max(float(p[meas_key]), 1e-12)) for p in mp
                     if p.get("predicted_error_bound")]
                if b:
                    ax.scatter([u for u, _ in b], [w for _, w in b], facecolors="none", edgecolors=colour,
                               marker="^", label="frequency, App. B bound", zorder=3)
                    vals += [u for u, _ in b]
                m = [(max(float(p[pred_key]), 1e-12), max(float(p["mitsuba_error"]), 1e-12)) for p in mp
                     if p.get("mitsuba_error") is not None]
                if m:
                    ax.scatter([u for u, _ in m], [w for _, w in m], facecolors="none", edgecolors=colour,
                               marker=marker, label="frequency vs Mitsuba 3 (sphere image)", zorder=3)
                    vals += [w for _, w in m]
        if vals:
            lo, hi = min(vals) / 2, max(vals) * 2
            ax.plot([lo, hi], [lo, hi], "k-", lw=0.8, label="predicted = measured")
            if pred_key == "predicted_seconds":
                ax.plot([lo, hi], [lo / 2, hi / 2], "k:", lw=0.6, label="factor 2")
                ax.plot([lo, hi], [lo * 2, hi * 2], "k:", lw=0.6)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"predicted {label}")
        ax.set_ylabel(f"measured {label}")
        ax.set_title(f"{name}\npredicted against measured {label.split()[-1]}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        paths[key] = out / key
        fig.savefig(paths[key], dpi=110)
        plt.close(fig)
    return paths

