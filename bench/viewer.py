"""Viewer frame time: SHRMs of order P = 0, 2, 3, 5 against a plain single-texture environment reflection.

Headless Chromium (Debian's, SwiftShader WebGL2: the flags of docs/facts.md) renders the viewer page
(``relight.server.viewer.mount_viewer`` on a bare app: no jobs needed) at 1280 x 720. Each configuration loads an SHRM
straight into the page (``window.relight.viewer.setShrm``): one R-centred component with (P + 1)^2 local layers
(S x 2S, float16, random band-limited content: timing does not depend on the values). The baseline shades the
same object with one texture lookup of the environment at R (``SHADING_PLAIN_ENV``), in the same run.

Frame time = wall time of one ``render()`` plus a 1-pixel ``readPixels`` (which waits for the frame), with the
camera turning 0.01 rad about +Y before every frame (so the per-frame work is really redone), median over rounds
that interleave the configurations (ABAB..., so drift hits all alike). Paths:

* ``distant`` — seed 000 §7.5: the local layers are made global once at load (eq. 8), then every frame sums them
  with the constant weights Yr_pq(V) into an S x 2S map (eq. 12) and looks it up once per pixel; the goal is
  <= 2x the baseline for P = 3.
* ``near`` — eq. 6 per pixel ((P + 1)^2 lookups and the harmonics per pixel), for reference.

Scenes: n = 1, 2, 4, 8 spheres (radius 1, on an arc 6 units from the viewer), each with its own P = 3 SHRM
(``ShrmViewer.setSceneObjects``; separate textures per object) and the distant viewer, so every frame computes n
view maps (eq. 12, one per object, for the direction from its centre to the camera). The field of view is the
same for every n (the 8-object arc's), so each object covers the same pixels. Ratio = frame time / the one-object
scene's, same run: what each further object costs.

``python3 bench/viewer.py [--quick]`` prints a Markdown table and writes ``bench/results/viewer.{md,json}``.
"""

from __future__ import annotations

import argparse
import base64
import json
import platform
import socket
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from relight import indexing

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight import sh, shrm  # noqa: E402
from relight.gl import layout as gl_layout  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-gpu-sandbox", "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--disable-quic"]
ORDERS = (0, 2, 3, 5)
WIDTH, HEIGHT = 1280, 720
GOAL_P, GOAL_RATIO = 3, 2.0
SCENE_SIZES = (1, 2, 4, 8)
SCENE_P = 3


def serve_viewer() -> tuple[str, Any]:
    """The viewer's static files on a free loopback port (uvicorn in a thread)."""
    import uvicorn
    from fastapi import FastAPI

    from relight.server.viewer import mount_viewer

    app = FastAPI()
    mount_viewer(app)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(app, log_level="error", access_log=False))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        if time.monotonic() > deadline:
            raise RuntimeError("the viewer server did not start")
        time.sleep(0.05)
    return f"http://127.0.0.1:{port}", server


def random_maps(rng: np.random.Generator, count: int, rows: int, order: int = 8) -> np.ndarray:
    l, m = indexing.healpy_lm(order)
    out = []
    for _ in range(count):
        alm = rng.normal(size=(3, indexing.healpy_size(order))) + 1j * rng.normal(size=(3, indexing.healpy_size(order)))
        alm[:, m == 0] = alm[:, m == 0].real
        out.append(np.abs(sh.synthesize(alm / (l + 1.0), order, rows)) + 0.2)
    return np.stack(out)


def shrm_payload(p_order: int, rows: int, rng: np.random.Generator) -> tuple[dict[str, Any], str]:
    if p_order == 0:
        comp = shrm.SHRMComponent("R", "radial", 8, 0, [(0, 0)], random_maps(rng, 1, rows), {})
    else:
        terms = shrm.terms_for("general", p_order)
        comp = shrm.SHRMComponent("R", "general", 8, p_order, terms, random_maps(rng, len(terms), rows), {})
    manifest, stack = gl_layout.layers_from_shrm(shrm.SHRM([comp]))
    return manifest, base64.b64encode(stack.astype("<f2").tobytes()).decode()


SETUP = """async ([w, h, envB64, envRows, background, obj]) => {
  const st = window.relight;
  const v = st.viewer;
  v.stop();
  v.setFixedSize([w, h]);
  const env = Uint8Array.from(atob(envB64), (c) => c.charCodeAt(0));
  v.setEnvironment(new Uint16Array(env.buffer), envRows, 2 * envRows);
  await st.setObject(obj);
  v.setOptions({ background, exposure: 0, tonemap: 'aces', rotation: 0.3 });
  return v.renderer.getContext().getParameter(v.renderer.getContext().VERSION);
}"""

MEASURE = """([manifest, b64, shading, mode, frames]) => {
  const v = window.relight.viewer;
  if (manifest) {
    const bin = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    v.setShrm(manifest, bin.buffer);
  }
  v.setOptions({ shading, mode });
  return v.benchmark(frames, { orbit: true, step: 0.01 });
}"""


MEASURE_SCENE = """([manifest, b64, n, frames]) => {
  const v = window.relight.viewer;
  const bin = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  const items = [];
  for (let k = 0; k < n; k += 1) {
    const a = (k - (n - 1) / 2) * 0.2;
    items.push({ name: `o${k}`, center: [6 * Math.sin(a), 0, -6 * Math.cos(a)], radius: 1, mode: 'distant',
      geometry: 'sphere', manifest, buffer: bin.buffer.slice(0) });
  }
  v.setSceneObjects(items);
  v.sceneHalfAngles = [0.9, 0.35]; // the same field of view for every n: each object covers the same pixels
  v.setOptions({ shading: 'shrm', mode: 'distant' });
  const res = v.benchmark(frames, { orbit: true, step: 0.01 });
  v.clearScene();
  return res;
}"""


def run(quick: bool) -> dict[str, Any]:
    from playwright.sync_api import sync_playwright

    rows = 64 if quick else 128
    frames, rounds = (5, 2) if quick else (10, 4)
    rng = np.random.default_rng(0)
    payloads = {p: shrm_payload(p, rows, rng) for p in ORDERS}
    env = random_maps(rng, 1, 2 * rows)[0]
    env_b64 = base64.b64encode(env.astype("<f2").tobytes()).decode()
    url, server = serve_viewer()
    results: dict[str, list[float]] = {}
    configs = [("plain", None, "plain", "distant")]
    for p in ORDERS:
        configs.append((f"P={p} distant", p, "shrm", "distant"))
    for p in ORDERS:
        configs.append((f"P={p} near", p, "shrm", "near"))
    try:
        with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
            ctx = pw.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=FLAGS, headless=True,
                                                        viewport={"width": WIDTH + 320, "height": HEIGHT})
            page = ctx.new_page()
            page.goto(url + "/")
            page.wait_for_function("window.relight && window.relight.ready === true", timeout=60_000)
            out: dict[str, Any] = {"gl_version": None, "objects": {}}
            for obj in ("sphere", "teapot"):
                out["gl_version"] = page.evaluate(SETUP, [WIDTH, HEIGHT, env_b64, 2 * rows, False, obj])
                for r in range(rounds):
                    for name, p, shading, mode in configs:
                        manifest, b64 = payloads[p] if p is not None else (None, None)
                        res = page.evaluate(MEASURE, [manifest, b64, shading, mode, frames])
                        results.setdefault(f"{obj}|{name}", []).append(res["median"])
                    print(f"  {obj}: round {r + 1}/{rounds} done", file=sys.stderr)
            page.evaluate(SETUP, [WIDTH, HEIGHT, env_b64, 2 * rows, False, "sphere"])
            manifest, b64 = payloads[SCENE_P]
            for r in range(rounds):
                for n in SCENE_SIZES:
                    res = page.evaluate(MEASURE_SCENE, [manifest, b64, n, frames])
                    results.setdefault(f"scene|{n} object{'s' if n > 1 else ''}", []).append(res["median"])
                print(f"  scenes: round {r + 1}/{rounds} done", file=sys.stderr)
            ctx.close()
    finally:
        server.should_exit = True
    table: dict[str, Any] = {}
    for key, values in results.items():
        obj, name = key.split("|")
        table.setdefault(obj, {})[name] = {"median_ms": statistics.median(values), "rounds_ms": values}
    for rows_ in table.values():
        base = rows_["plain"]["median_ms"] if "plain" in rows_ else rows_["1 object"]["median_ms"]
        for row in rows_.values():
            row["ratio"] = row["median_ms"] / base
    goal = table["sphere"][f"P={GOAL_P} distant"]["ratio"]
    return {
        "benchmark": "viewer frame time (headless Chromium, SwiftShader WebGL2)",
        "resolution": [WIDTH, HEIGHT], "shrm_rows": rows, "frames_per_round": frames, "rounds": rounds,
        "gl_version": out["gl_version"], "machine": platform.platform(), "python": platform.python_version(),
        "background": False, "results": table,
        "goal": {"P": GOAL_P, "path": "distant", "max_ratio": GOAL_RATIO, "ratio": goal, "met": goal <= GOAL_RATIO},
    }


def markdown(res: dict[str, Any]) -> str:
    lines = [f"# Viewer frame time ({res['resolution'][0]} x {res['resolution'][1]}, {res['gl_version']})", "",
             f"SHRM maps {res['shrm_rows']} x {2 * res['shrm_rows']} float16; median of {res['rounds']} interleaved "
             f"rounds x {res['frames_per_round']} frames, camera turning every frame; ratio = frame time / plain "
             "environment reflection, same run. Background off (object shading only).", ""]
    for obj, rows in res["results"].items():
        base = "plain" if obj != "scene" else "1 object"
        lines += [f"## {obj}" + (f" (P = {SCENE_P} SHRM per object, distant viewer)" if obj == "scene" else ""), "",
                  f"| configuration | frame time (ms) | ratio to {base} |", "|---|---:|---:|"]
        for name, row in rows.items():
            lines.append(f"| {name} | {row['median_ms']:.1f} | {row['ratio']:.2f} |")
        lines.append("")
    g = res["goal"]
    lines.append(f"Goal: P = {g['P']} ({g['path']}) <= {g['max_ratio']}x plain on the sphere: ratio {g['ratio']:.2f} "
                 f"— {'met' if g['met'] else 'NOT met'}.")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller maps, fewer frames")
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "results")
    args = parser.parse_args()
    res = run(args.quick)
    text = markdown(res)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "viewer.json").write_text(json.dumps(res, indent=2) + "\n")
    (args.out / "viewer.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
