"""Service benchmark: job overhead, cached download throughput, end-to-end time on the sample maps.

    PYTHONPATH=. python3 bench/service.py [--out bench/results/service.json] [--seconds 5] [--concurrency 16]

Starts ``relight serve`` (embedded cluster, 2 worker processes) on a free loopback port with a fresh data
directory, then measures:

1. **Job overhead** for a tiny job (32 x 64 map, low order): client submit -> ``end`` event, minus the core's
   compute time (and, separately, minus the whole worker-task time). Goal: under 50 ms.
2. **Cached GET throughput**: ``GET /shrms/{id}/coefficients.bin`` from many keep-alive connections at once,
   requests per second and latency percentiles. The load generator is a minimal asyncio HTTP/1.1 client (an
   httpx client would spend more CPU than the server on this 2-core machine). Goal: >= 1000 requests/s.
3. **End to end** on each sample map (1024 x 512 EXR): upload, submit (Phong s = 32, epsilon = 0.01), wait,
   download; next to the server's predicted seconds.

Prints a markdown table and writes JSON. Timings are medians unless stated; this is not a test.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from relight.client.sdk import RelightClient  # noqa: E402


def start_server(data: Path, workers: int = 2) -> tuple[subprocess.Popen[bytes], str, Path]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("RELIGHT_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    env.update({"RELIGHT_LOG_LEVEL": "warning", "RELIGHT_N_WORKERS": str(workers), "RELIGHT_THREADS": "1"})
    data.mkdir(parents=True, exist_ok=True)
    log = data / "server.log"
    fh = open(log, "wb")  # noqa: SIM115 - lives as long as the server
    proc = subprocess.Popen([sys.executable, "-m", "relight.cli", "serve", "--port", "0", "--data", str(data),
                             "--no-preload"], env=env, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        m = re.search(r"relight: serving (http://\S+)", log.read_text(errors="replace"))
        if m:
            return proc, m.group(1), log
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGKILL)
    raise SystemExit(f"server did not start:\n{log.read_text(errors='replace')[-3000:]}")


def stop_server(proc: subprocess.Popen[bytes]) -> None:
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=30)


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, max(0, round(q / 100 * (len(s) - 1))))]


# ------------------------------------------------------------------------------------------------ 1. overhead
def tiny_map(tmp: Path) -> bytes:
    import numpy as np

    from relight.envmap import write_exr

    rng = np.random.default_rng(0)
    p = tmp / "tiny.exr"
    write_exr(p, (0.5 + rng.random((32, 64, 3))).astype(np.float32))
    return p.read_bytes()


def job_overhead(c: RelightClient, envmap: str, n: int) -> dict[str, Any]:
    rows: list[dict[str, float]] = []
    for i in range(n + 2):
        t0 = time.perf_counter()
        job = c.submit(envmap, "phong:s=8", order=4 + i % 16, size=16 + 2 * (i // 16))
        end = None
        for j in c.events(job.id, timeout=60):
            end = j
        wall = time.perf_counter() - t0
        assert end is not None and end.state == "succeeded", end
        m = end.measured
        assert m is not None and m.compute_seconds is not None and m.task_seconds is not None
        if i >= 2:  # the first two warm the workers
            rows.append({"wall": wall, "compute": m.compute_seconds, "task": m.task_seconds,
                         "server": m.seconds or 0.0})
    over_compute = [r["wall"] - r["compute"] for r in rows]
    over_task = [r["wall"] - r["task"] for r in rows]
    return {
        "jobs": len(rows),
        "wall_median_s": statistics.median(r["wall"] for r in rows),
        "compute_median_s": statistics.median(r["compute"] for r in rows),
        "task_median_s": statistics.median(r["task"] for r in rows),
        "overhead_vs_compute_median_s": statistics.median(over_compute),
        "overhead_vs_compute_p90_s": pct(over_compute, 90),
        "overhead_vs_task_median_s": statistics.median(over_task),
    }


# ------------------------------------------------------------------------------------------------ 2. cached GETs
async def _get_loop(host: str, port: int, path: str, stop_at: float, lat: list[float], sizes: list[int]) -> None:
    reader, writer = await asyncio.open_connection(host, port)
    request = f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\n\r\n".encode()
    try:
        while time.perf_counter() < stop_at:
            t = time.perf_counter()
            writer.write(request)
            head = await reader.readuntil(b"\r\n\r\n")
            status = int(head[9:12])
            m = re.search(rb"(?i)content-length:\s*(\d+)", head)
            length = int(m.group(1)) if m else 0
            body = await reader.readexactly(length)
            if status != 200:
                raise RuntimeError(f"GET {path}: {status} {body[:200]!r}")
            lat.append(time.perf_counter() - t)
            sizes.append(length)
    finally:
        writer.close()


async def _cached_gets(url: str, path: str, seconds: float, concurrency: int) -> dict[str, Any]:
    m = re.match(r"http://([^:/]+):(\d+)", url)
    assert m
    host, port = m.group(1), int(m.group(2))
    lat: list[float] = []
    sizes: list[int] = []
    await _get_loop(host, port, path, time.perf_counter() + 0.5, [], [])  # warm-up
    t0 = time.perf_counter()
    stop_at = t0 + seconds
    await asyncio.gather(*(_get_loop(host, port, path, stop_at, lat, sizes) for _ in range(concurrency)))
    elapsed = time.perf_counter() - t0
    return {
        "path": path, "concurrency": concurrency, "seconds": elapsed, "requests": len(lat),
        "requests_per_s": len(lat) / elapsed, "bytes_per_response": sizes[0] if sizes else 0,
        "latency_p50_ms": 1e3 * pct(lat, 50), "latency_p99_ms": 1e3 * pct(lat, 99),
    }


# ------------------------------------------------------------------------------------------------ 3. end to end
def end_to_end(c: RelightClient, maps: list[Path]) -> list[dict[str, Any]]:
    rows = []
    for p in maps:
        t0 = time.perf_counter()
        env = c.upload_envmap(p)
        t_up = time.perf_counter() - t0
        plan = c.plan(env.id, "phong:s=32", epsilon=0.01)
        job = c.submit(env.id, "phong:s=32", epsilon=0.01)
        job = c.wait(job.id, timeout=300)
        data = c.download(job.id)
        total = time.perf_counter() - t0
        m = job.measured
        rows.append({
            "map": p.name, "size": f"{env.width}x{env.height}", "upload_s": t_up, "total_s": total,
            "F_B": plan.orders.F_B, "output": f"{plan.output.width}x{plan.output.height}",
            "predicted_s": plan.predicted_seconds, "task_s": m.task_seconds if m else None,
            "compute_s": m.compute_seconds if m else None, "exr_bytes": len(data),
        })
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "service.json"))
    ap.add_argument("--jobs", type=int, default=30, help="tiny jobs for the overhead measurement")
    ap.add_argument("--seconds", type=float, default=5.0, help="duration of the GET load")
    ap.add_argument("--concurrency", type=int, default=16)
    ap.add_argument("--maps", default=str(REPO / "data" / "envmaps"))
    args = ap.parse_args()

    results: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "python": sys.version.split()[0]}}
    with tempfile.TemporaryDirectory(prefix="relight-bench-") as tmp:
        proc, url, _ = start_server(Path(tmp) / "data")
        try:
            with RelightClient(url, timeout=300) as c:
                env = c.upload_envmap(tiny_map(Path(tmp)))
                results["job_overhead"] = job_overhead(c, env.id, args.jobs)
                job = c.wait(c.submit(env.id, "phong:s=8", order=6, size=64).id, timeout=60)
                results["cached_get"] = asyncio.run(_cached_gets(url, f"/shrms/{job.id}/coefficients.bin",
                                                                 args.seconds, args.concurrency))
                results["cached_get_exr"] = asyncio.run(_cached_gets(url, f"/shrms/{job.id}/coefficients.exr",
                                                                     args.seconds, args.concurrency))
                maps = sorted(Path(args.maps).glob("*.exr"))
                results["end_to_end"] = end_to_end(c, maps)
        finally:
            stop_server(proc)

    o, g, ge = results["job_overhead"], results["cached_get"], results["cached_get_exr"]
    print("\n## relight service benchmark\n")
    print("| measurement | value | goal |\n|---|---|---|")
    print(f"| job overhead (submit -> done, minus core compute), median | "
          f"{1e3 * o['overhead_vs_compute_median_s']:.1f} ms | < 50 ms |")
    print(f"| job overhead, p90 | {1e3 * o['overhead_vs_compute_p90_s']:.1f} ms | |")
    print(f"| job overhead minus the whole worker task, median | {1e3 * o['overhead_vs_task_median_s']:.1f} ms | |")
    print(f"| tiny job: wall / task / core compute, median | {1e3 * o['wall_median_s']:.1f} / "
          f"{1e3 * o['task_median_s']:.1f} / {1e3 * o['compute_median_s']:.1f} ms | |")
    for name, r in (("coefficients.bin", g), ("coefficients.exr", ge)):
        print(f"| cached GET {name} ({r['bytes_per_response']} B, {r['concurrency']} connections) | "
              f"{r['requests_per_s']:.0f} req/s, p50 {r['latency_p50_ms']:.2f} ms, p99 {r['latency_p99_ms']:.2f} ms"
              " | >= 1000 req/s |")
    print("\n| sample map | size | F_B | output | upload | predicted | task | core | end to end |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results["end_to_end"]:
        print(f"| {r['map']} | {r['size']} | {r['F_B']} | {r['output']} | {r['upload_s']:.3f} s | "
              f"{r['predicted_s']:.3f} s | {r['task_s']:.3f} s | {r['compute_s']:.3f} s | {r['total_s']:.3f} s |")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(f"\nwrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
