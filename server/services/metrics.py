"""Counters and the Prometheus text exposition (format 0.0.4) for ``GET /metrics``."""

from __future__ import annotations

import bisect
import gc
import time
from collections import Counter
from typing import Any

#: Histogram buckets for job durations, seconds.
BUCKETS = (0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0)
#: Histogram buckets for garbage-collector pauses, seconds (a pause holds the GIL: nothing in the process runs).
GC_BUCKETS = (0.001, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 1.0)


class Histogram:
    def __init__(self, buckets: tuple[float, ...] = BUCKETS) -> None:
        self.buckets = buckets
        self.counts = [0] * (len(buckets) + 1)
        self.total = 0.0
        self.n = 0

    def observe(self, v: float) -> None:
        self.counts[bisect.bisect_left(self.buckets, v)] += 1
        self.total += v
        self.n += 1

    def lines(self, name: str) -> list[str]:
        out = []
        acc = 0
        for b, c in zip(self.buckets, self.counts, strict=False):
            acc += c
            out.append(f'{name}_bucket{{le="{b:g}"}} {acc}')
        out.append(f'{name}_bucket{{le="+Inf"}} {self.n}')
        out.append(f"{name}_sum {self.total:.6f}")
        out.append(f"{name}_count {self.n}")
        return out


class GcPauses:
    """How long each of the cyclic garbage collector's collections stopped this process, per generation, once
    :meth:`start` has registered the ``gc`` callback (the server process: :func:`relight.server.run.settle_heap`)."""

    def __init__(self) -> None:
        self.by_generation = [Histogram(GC_BUCKETS) for _ in range(3)]
        self._t0 = 0.0

    def _callback(self, phase: str, info: dict[str, Any]) -> None:
        if phase == "start":
            self._t0 = time.perf_counter()
        else:
            self.by_generation[info["generation"]].observe(time.perf_counter() - self._t0)

    def start(self) -> None:
        if self._callback not in gc.callbacks:
            gc.callbacks.append(self._callback)

    def stop(self) -> None:
        if self._callback in gc.callbacks:
            gc.callbacks.remove(self._callback)

    def lines(self) -> list[str]:
        out = ["# HELP relight_gc_pause_seconds Collections of the cyclic garbage collector in the API process "
               "by generation, and how long each stopped it.",
               "# TYPE relight_gc_pause_seconds histogram"]
        for generation, h in enumerate(self.by_generation):
            out += [line.replace("{", f'{{generation="{generation}",', 1) if "{" in line
                    else line.replace(" ", f'{{generation="{generation}"}} ', 1)
                    for line in h.lines("relight_gc_pause_seconds")]
        out += ["# HELP relight_gc_frozen_objects Objects alive at start-up, kept out of the collector's scans "
                "(gc.freeze).", "# TYPE relight_gc_frozen_objects gauge",
                f"relight_gc_frozen_objects {gc.get_freeze_count()}"]
        return out


class Metrics:
    def __init__(self) -> None:
        self.counters: Counter[str] = Counter()
        self.job_seconds = Histogram()
        self.compute_seconds = Histogram()
        self.gc = GcPauses()

    def inc(self, name: str, n: int = 1) -> None:
        self.counters[name] += n

    def render(self, jobs_by_state: dict[str, int], workers: int) -> str:
        lines = [
            "# HELP relight_jobs Jobs in the job table by state.",
            "# TYPE relight_jobs gauge",
        ]
        for state in ("queued", "running", "succeeded", "failed", "cancelled"):
            lines.append(f'relight_jobs{{state="{state}"}} {jobs_by_state.get(state, 0)}')
        help_ = {
            "jobs_created_total": "Jobs created (distinct job ids).",
            "job_submissions_total": "Submissions of jobs to the Dask cluster.",
            "job_runs_total": "Times a worker started a job (more than submissions after worker loss).",
            "jobs_succeeded_total": "Jobs that finished with a result (this process).",
            "jobs_failed_total": "Jobs that failed (this process).",
            "jobs_cancelled_total": "Jobs cancelled (this process).",
            "cache_hits_total": "Submissions answered from an existing result.",
            "results_recomputed_total": "Results found corrupt or missing on read and recomputed.",
            "uploads_total": "Environment maps accepted.",
            "uploads_rejected_total": "Uploads rejected (size, type, header, content).",
        }
        for key, text in help_.items():
            name = f"relight_{key}"
            lines += [f"# HELP {name} {text}", f"# TYPE {name} counter", f"{name} {self.counters.get(key, 0)}"]
        lines += ["# HELP relight_job_duration_seconds Submission to result, seconds.",
                  "# TYPE relight_job_duration_seconds histogram"]
        lines += self.job_seconds.lines("relight_job_duration_seconds")
        lines += ["# HELP relight_job_compute_seconds Time in the numerical core, seconds.",
                  "# TYPE relight_job_compute_seconds histogram"]
        lines += self.compute_seconds.lines("relight_job_compute_seconds")
        lines += ["# HELP relight_workers Dask workers connected.", "# TYPE relight_workers gauge",
                  f"relight_workers {workers}"]
        lines += self.gc.lines()
        return "\n".join(lines) + "\n"
