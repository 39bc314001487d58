"""Load against a real server (issue 12, item 6): the active-job cap, expensive plans beside /health, many result
downloads at once.

    PYTHONPATH=. python3 bench/load.py [--jobs 200] [--cap 8] [--plans 50] [--gets 500] [--phases cap,plans,gets]
                                       [--out bench/results/load.json]

Starts ``relight serve`` (embedded cluster, two worker processes, the test servers' small limits) with
``RELIGHT_MAX_ACTIVE_JOBS=cap`` on a fresh data directory, then:

1. **Cap.** ``--jobs`` distinct submissions sent at once with a bare HTTP client: how many 202, how many 429 (each
   with ``Retry-After``), any 5xx. Then the same number of distinct jobs through ``AsyncRelightClient`` all at
   once: the SDK follows ``Retry-After`` by itself; every job must succeed.
2. **Plans.** ``--plans`` concurrent ``POST /plan`` of an expensive request (Torrance-Sparrow, small epsilon:
   planned in the sandbox pool) while ``/health`` is asked every 50 ms: its latency percentiles and the plans'
   statuses.
3. **Downloads.** ``--gets`` concurrent ``GET`` of one large result file (``coefficients.bin``): statuses, the
   server process's resident memory before, at its peak and after.

Prints a markdown table and writes JSON. Numbers depend on the machine and its load; this is not a test.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import psutil

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from relight.client.async_sdk import AsyncRelightClient  # noqa: E402
from tests.service.support import exr_bytes, make_envmap, start_server  # noqa: E402

EXPENSIVE = {"kind": "torrance-sparrow", "alpha": 0.2, "fresnel": "none"}


def pct(values: list[float], q: float) -> float:
    return sorted(values)[min(len(values) - 1, int(q * len(values)))] if values else float("nan")


class HealthWatch:
    """``/health`` asked every 50 ms on its own connection while a phase runs: latencies (inf for a non-200)."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.latencies: list[float] = []
        self._stop = asyncio.Event()
        self._task: asyncio.Task[None] | None = None

    async def _run(self) -> None:
        async with httpx.AsyncClient(base_url=self.url, timeout=30) as http:
            while not self._stop.is_set():
                t = time.perf_counter()
                r = await http.get("/health")
                self.latencies.append(time.perf_counter() - t if r.status_code == 200 else float("inf"))
                await asyncio.sleep(0.05)

    def __enter__(self) -> HealthWatch:
        self._task = asyncio.create_task(self._run())
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()

    async def summary(self, prefix: str = "health") -> dict[str, Any]:
        if self._task is not None:
            await self._task
        lat = self.latencies
        return {f"{prefix}_calls": len(lat), f"{prefix}_p50_ms": round(1e3 * pct(lat, 0.5), 1),
                f"{prefix}_p99_ms": round(1e3 * pct(lat, 0.99), 1),
                f"{prefix}_max_ms": round(1e3 * max(lat), 1) if lat else None,
                f"{prefix}_over_100ms": sum(t > 0.1 for t in lat)}


async def cap_phase(url: str, env: str, jobs: int) -> dict[str, Any]:
    limits = httpx.Limits(max_connections=jobs, max_keepalive_connections=jobs)
    async with httpx.AsyncClient(base_url=url, timeout=300, limits=limits) as http:
        answers = await asyncio.gather(*(http.post("/shrms", json={"envmap": env, "brdf": "phong:s=16",
                                                                   "epsilon": 0.05, "size": 8 + k})
                                         for k in range(jobs)))
        codes = [r.status_code for r in answers]
        retry_after = all("retry-after" in r.headers for r in answers if r.status_code == 429)
        for r in answers:  # the accepted ones are cancelled: the SDK phase starts from an empty cap
            if r.status_code == 202:
                await http.delete(f"/jobs/{r.json()['id']}")
    t0 = time.monotonic()
    async with AsyncRelightClient(url, timeout=600, limits=limits) as c:

        async def one(k: int) -> str:
            job = await c.submit(env, "phong:s=16", epsilon=0.05, size=8 + jobs + k)
            while job.state not in ("succeeded", "failed", "cancelled"):
                await asyncio.sleep(0.5)
                job = await c.get_job(job.id)
            return str(job.state)

        with HealthWatch(url) as watch:
            states = await asyncio.gather(*(one(k) for k in range(jobs)))
    return {**await watch.summary("sdk_health"),
            "accepted": codes.count(202), "refused_429": codes.count(429), "retry_after_on_every_429": retry_after,
            "server_errors": sum(c >= 500 for c in codes), "sdk_jobs": jobs,
            "sdk_succeeded": states.count("succeeded"), "sdk_seconds": round(time.monotonic() - t0, 1)}


async def plan_phase(url: str, env: str, plans: int) -> dict[str, Any]:
    async with httpx.AsyncClient(base_url=url, timeout=600,
                                 limits=httpx.Limits(max_connections=plans + 4)) as http:
        t0 = time.monotonic()
        with HealthWatch(url) as watch:
            answers = await asyncio.gather(*(http.post("/plan", json={"envmap": env, "brdf": EXPENSIVE,
                                                                       "epsilon": 0.003 + 0.00001 * k})
                                             for k in range(plans)), return_exceptions=True)
        seconds = time.monotonic() - t0
    codes = [a.status_code if isinstance(a, httpx.Response) else type(a).__name__ for a in answers]
    return {"plans": plans, "statuses": {str(c): codes.count(c) for c in set(codes)}, "seconds": round(seconds, 1),
            **await watch.summary()}


async def get_phase(url: str, env: str, gets: int, server_pid: int) -> dict[str, Any]:
    proc = psutil.Process(server_pid)
    async with httpx.AsyncClient(base_url=url, timeout=600,
                                 limits=httpx.Limits(max_connections=gets, max_keepalive_connections=gets)) as http:
        job = (await http.post("/shrms", json={"envmap": env, "brdf": {"kind": "microfacet", "sigma": 0.3},
                                               "order": 8, "p_order": 4, "size": 128})).json()
        while job["state"] not in ("succeeded", "failed"):
            await asyncio.sleep(0.5)
            job = (await http.get(f"/jobs/{job['id']}")).json()
        path = f"/shrms/{job['id']}/coefficients.bin"
        size = len((await http.get(path)).content)
        rss_before = proc.memory_info().rss
        peak = [rss_before]
        done = threading.Event()

        def sample() -> None:
            while not done.is_set():
                peak[0] = max(peak[0], proc.memory_info().rss)
                time.sleep(0.02)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        t0 = time.monotonic()

        async def one() -> int:
            r = await http.get(path)
            return r.status_code if len(r.content) == size else -1

        codes = await asyncio.gather(*(one() for _ in range(gets)), return_exceptions=True)
        seconds = time.monotonic() - t0
        done.set()
        sampler.join()
    statuses = [c if isinstance(c, int) else type(c).__name__ for c in codes]
    return {"gets": gets, "file_mib": round(size / 2**20, 2), "statuses": {str(c): statuses.count(c)
                                                                          for c in set(statuses)},
            "seconds": round(seconds, 1), "rss_before_mib": round(rss_before / 2**20),
            "rss_peak_mib": round(peak[0] / 2**20), "rss_after_mib": round(proc.memory_info().rss / 2**20),
            "peak_growth_in_files": round((peak[0] - rss_before) / size, 1)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jobs", type=int, default=200)
    ap.add_argument("--cap", type=int, default=8)
    ap.add_argument("--plans", type=int, default=50)
    ap.add_argument("--gets", type=int, default=500)
    ap.add_argument("--phases", default="cap,plans,gets", help="which phases to run (comma-separated)")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "load.json")
    args = ap.parse_args()
    phases = set(args.phases.split(","))
    with tempfile.TemporaryDirectory() as d:
        data = Path(d)
        server = start_server(data, {"RELIGHT_MAX_ACTIVE_JOBS": str(args.cap)})
        try:
            with httpx.Client(base_url=server.url, timeout=120) as http:
                env = http.post("/envmaps", content=exr_bytes(make_envmap(64, seed=800), data)).json()["id"]
            res: dict[str, Any] = {"cap": args.cap, "load_before": list(psutil.getloadavg())}
            if "cap" in phases:
                res["cap_phase"] = asyncio.run(cap_phase(server.url, env, args.jobs))
            if "plans" in phases:
                res["plan_phase"] = asyncio.run(plan_phase(server.url, env, args.plans))
            if "gets" in phases:
                res["get_phase"] = asyncio.run(get_phase(server.url, env, args.gets, server.pid))
            log = server.output()
            res["server_log_tracebacks"] = log.count("Traceback")
        finally:
            server.stop()
    print("| phase | result |\n|---|---|")
    print(f"| load average (1, 5, 15 min) before | {res['load_before']} |")
    if "cap_phase" in res:
        c = res["cap_phase"]
        print(f"| {args.jobs} submissions at once, cap {args.cap} | {c['accepted']} accepted, {c['refused_429']} x "
              f"429 (Retry-After on each: {c['retry_after_on_every_429']}), {c['server_errors']} x 5xx |")
        print(f"| {args.jobs} jobs through the SDK at once | {c['sdk_succeeded']} succeeded in {c['sdk_seconds']} s; "
              f"/health p50 {c['sdk_health_p50_ms']} ms, p99 {c['sdk_health_p99_ms']} ms, max "
              f"{c['sdk_health_max_ms']} ms ({c['sdk_health_calls']} calls, {c['sdk_health_over_100ms']} over "
              "100 ms) |")
    if "plan_phase" in res:
        p = res["plan_phase"]
        print(f"| {args.plans} expensive /plan at once | {p['statuses']} in {p['seconds']} s; /health p50 "
              f"{p['health_p50_ms']} ms, p99 {p['health_p99_ms']} ms, max {p['health_max_ms']} ms "
              f"({p['health_calls']} calls, {p['health_over_100ms']} over 100 ms) |")
    if "get_phase" in res:
        g = res["get_phase"]
        print(f"| {args.gets} GETs of a {g['file_mib']} MiB result | {g['statuses']} in {g['seconds']} s; server "
              f"RSS {g['rss_before_mib']} -> peak {g['rss_peak_mib']} MiB ({g['peak_growth_in_files']} files' "
              f"worth), after {g['rss_after_mib']} MiB |")
    print(f"| tracebacks in the server log | {res['server_log_tracebacks']} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2))
    c = res.get("cap_phase")
    ok = not res["server_log_tracebacks"] and (c is None or (c["server_errors"] == 0 and c["retry_after_on_every_429"]
                                                             and c["sdk_succeeded"] == args.jobs))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
