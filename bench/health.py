"""``GET /health`` latency, idle and under concurrent API load (issue 12, item 1: within 100 ms under any load).

    PYTHONPATH=. python3 bench/health.py [--clients 16] [--seconds 30] [--out bench/results/health.json]

Starts ``relight serve`` (embedded cluster, two worker processes) on a fresh data directory, uploads one map, then:

1. **Idle.** 500 sequential ``/health`` calls on one connection: latency percentiles (the request path's own cost).
2. **Load.** ``--clients`` concurrent clients loop over ``GET /jobs``, ``GET /envmaps/{id}``, ``POST /plan`` (a
   Phong plan: planned in the sandbox pool) and SHRM submissions for ``--seconds`` while ``/health`` is asked every
   50 ms on its own connection: its percentiles, calls over 100 ms, and the load requests answered. Asked twice:
   ``loaded`` from a process of its own (a blocking client: the server's latency), ``loaded_in_client_loop`` from
   the event loop that also drives the load clients (what earlier versions reported: it adds the wait for that
   loop, busy parsing the load's answers on the same CPUs).
3. **The machine's floor.** While loaded, a process of its own that does nothing but sleep 50 ms at a time reports
   how late it wakes up (``wakeup_delay``): no server can answer faster than the operating system runs it, so a
   ``/health`` p99 near this floor is the machine's, not the server's. And the server's event-loop thread: CPU
   seconds it ran and seconds it waited for a CPU (``/proc/PID/task/PID/schedstat``).

4. **The garbage collector.** Each setting of ``--freeze`` (default both, side by side in one run: ``on`` is the
   server's default, ``off`` sets ``RELIGHT_GC_FREEZE=0``) starts its own server; after the load, the server's
   ``/metrics`` says how many full (generation 2) collections ran, how long they stopped it in all and at most
   (bucket bound), and how many objects start-up froze out of the collector's scans.

Prints a markdown table and writes JSON, with the machine's load average. Not a test: numbers depend on the machine.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.service.support import exr_bytes, make_envmap, start_server  # noqa: E402


def pct(values: list[float], q: float) -> float:
    return sorted(values)[min(len(values) - 1, int(q * len(values)))] if values else float("nan")


def summary(latencies: list[float]) -> dict[str, Any]:
    ms = [1000 * x for x in latencies]
    return {"calls": len(ms), "p50_ms": round(pct(ms, 0.5), 2), "p99_ms": round(pct(ms, 0.99), 2),
            "max_ms": round(max(ms), 2), "over_100ms": sum(m > 100 for m in ms)}


async def health_calls(url: str, stop: asyncio.Event | None, n: int, interval: float) -> list[float]:
    out: list[float] = []
    async with httpx.AsyncClient(base_url=url, timeout=30) as http:
        while (stop is None and len(out) < n) or (stop is not None and not stop.is_set()):
            t = time.perf_counter()
            r = await http.get("/health")
            out.append(time.perf_counter() - t if r.status_code == 200 else float("inf"))
            if interval:
                await asyncio.sleep(interval)
    return out


def watch_in_process(url: str, seconds: float, go: Any, out: Any) -> None:
    """``/health`` every 50 ms for ``seconds`` from ``go`` on, from this (separate) process, on one keep-alive
    connection."""
    lat: list[float] = []
    with httpx.Client(base_url=url, timeout=30) as http:
        go.wait()
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            t = time.perf_counter()
            r = http.get("/health")
            lat.append(time.perf_counter() - t if r.status_code == 200 else float("inf"))
            time.sleep(0.05)
    out.send(lat)


def wakeup_delays(seconds: float, go: Any, out: Any) -> None:
    """How late a 50 ms sleep ends, again and again for ``seconds`` from ``go`` on, in this (separate, otherwise
    idle) process."""
    late: list[float] = []
    go.wait()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        t = time.perf_counter()
        time.sleep(0.05)
        late.append(time.perf_counter() - t - 0.05)
    out.send(late)


def schedstat(pid: int) -> tuple[float, float]:
    """(seconds run on a CPU, seconds waited for one) of the process's main thread."""
    run_ns, wait_ns, _ = open(f"/proc/{pid}/task/{pid}/schedstat").read().split()
    return int(run_ns) / 1e9, int(wait_ns) / 1e9


async def loader(url: str, env: str, k: int, stop: asyncio.Event, counts: dict[str, int]) -> None:
    async with httpx.AsyncClient(base_url=url, timeout=120) as http:
        i = 0
        while not stop.is_set():
            i += 1
            step = i % 4
            if step == 0:
                r = await http.get("/jobs", params={"limit": 100})
            elif step == 1:
                r = await http.get(f"/envmaps/{env}")
            elif step == 2:
                r = await http.post("/plan", json={"envmap": env, "brdf": {"kind": "phong", "s": 8 + k + i % 7},
                                                   "epsilon": 0.05})
            else:
                r = await http.post("/shrms", json={"envmap": env, "brdf": "phong:s=8", "epsilon": 0.05,
                                                    "size": 8 + (1000 * k + i) % 200})
            key = str(r.status_code)
            counts[key] = counts.get(key, 0) + 1


async def run(url: str, env: str, clients: int, seconds: float, server_pid: int) -> dict[str, Any]:
    idle = summary(await health_calls(url, None, 500, 0.0))
    stop = asyncio.Event()
    counts: dict[str, int] = {}
    ctx = multiprocessing.get_context("spawn")
    go = ctx.Event()
    receive, send = ctx.Pipe(duplex=False)
    own = ctx.Process(target=watch_in_process, args=(url, seconds, go, send))
    own.start()
    receive_floor, send_floor = ctx.Pipe(duplex=False)
    floor = ctx.Process(target=wakeup_delays, args=(seconds, go, send_floor))
    floor.start()
    await asyncio.sleep(5.0)  # both interpreters start (imports) before the load does
    go.set()
    sched0 = schedstat(server_pid)
    watch = asyncio.create_task(health_calls(url, stop, 0, 0.05))
    load = [asyncio.create_task(loader(url, env, k, stop, counts)) for k in range(clients)]
    await asyncio.sleep(seconds)
    stop.set()
    sched1 = schedstat(server_pid)
    in_loop = summary(await watch)
    await asyncio.gather(*load)
    loaded = summary(await asyncio.to_thread(receive.recv))
    wakeup = summary(await asyncio.to_thread(receive_floor.recv))
    own.join()
    floor.join()
    return {"idle": idle, "loaded": loaded, "loaded_in_client_loop": in_loop, "wakeup_delay": wakeup,
            "load_requests": counts,
            "server_loop_thread": {"ran_s": round(sched1[0] - sched0[0], 2),
                                   "waited_for_cpu_s": round(sched1[1] - sched0[1], 2)},
            "loadavg": list(os.getloadavg())}


def gc_pauses(url: str) -> dict[str, Any]:
    """Full collections since start-up from the server's ``/metrics``: count, total seconds, the smallest bucket
    bound that holds the longest, and the frozen objects."""
    import re

    text = httpx.get(f"{url}/metrics", timeout=30).text
    val: dict[str, float] = {}
    for m in re.finditer(r'^relight_gc_pause_seconds_(sum|count)\{generation="2"\} (\S+)$', text, re.M):
        val[m[1]] = float(m[2])
    buckets = [(float(m[1]), float(m[2])) for m in re.finditer(
        r'^relight_gc_pause_seconds_bucket\{generation="2",le="([0-9.e+-]+)"\} (\S+)$', text, re.M)]
    longest = next((le for le, n in buckets if n >= val["count"]), float("inf"))
    frozen = re.search(r"^relight_gc_frozen_objects (\S+)$", text, re.M)
    assert frozen is not None, text[-2000:]
    return {"full_collections": int(val["count"]), "full_seconds": round(val["sum"], 3),
            "longest_at_most_ms": longest * 1000, "frozen_objects": int(float(frozen[1]))}


def one(freeze: bool, clients: int, seconds: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="relight-health-bench-") as tmp:
        server = start_server(Path(tmp), {"RELIGHT_MAX_ACTIVE_JOBS": "64", "RELIGHT_GC_FREEZE": str(int(freeze))})
        try:
            with httpx.Client(base_url=server.url, timeout=60) as http:
                r = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=5), Path(tmp)))
                env = r.json()["id"]
            res = asyncio.run(run(server.url, env, clients, seconds, server.pid))
            res["gc"] = gc_pauses(server.url)
        finally:
            server.stop()
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "health.json")
    ap.add_argument("--freeze", default="on,off", help="gc.freeze at start-up: on, off or both (on,off)")
    args = ap.parse_args()
    modes = [m.strip() for m in args.freeze.split(",")]
    assert set(modes) <= {"on", "off"}, args.freeze
    runs = {f"freeze_{m}": one(m == "on", args.clients, args.seconds) for m in modes}
    out = {"clients": args.clients, "seconds": args.seconds, "runs": runs}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=2))
    print("| server | /health (or the floor) | calls | p50 ms | p99 ms | max ms | over 100 ms |")
    print("|---|---|---|---|---|---|---|")
    for mode, res in runs.items():
        for name in ("idle", "loaded", "loaded_in_client_loop", "wakeup_delay"):
            s = res[name]
            print(f"| {mode} | {name} | {s['calls']} | {s['p50_ms']} | {s['p99_ms']} | {s['max_ms']} | "
                  f"{s['over_100ms']} |")
    print("\n| server | full collections | their seconds | longest (at most) ms | frozen objects | loop ran s | "
          "loop waited for a CPU s | load requests | load average |")
    print("|---|---|---|---|---|---|---|---|---|")
    for mode, res in runs.items():
        g, loop = res["gc"], res["server_loop_thread"]
        print(f"| {mode} | {g['full_collections']} | {g['full_seconds']} | {g['longest_at_most_ms']:g} | "
              f"{g['frozen_objects']} | {loop['ran_s']} | {loop['waited_for_cpu_s']} | {res['load_requests']} | "
              f"{', '.join(f'{x:.1f}' for x in res['loadavg'])} |")
    print(f"\n{args.clients} load clients for {args.seconds} s per server")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
