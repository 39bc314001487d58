"""Counters and the Prometheus text exposition (format 0.0.4) for ``GET /metrics``."""

from __future__ import annotations

import bisect
from collections import Counter

#: Histogram buckets for job durations, seconds.
BUCKETS = (0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0)


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


class Metrics:
    def __init__(self) -> None:
        self.counters: Counter[str] = Counter()
        self.job_seconds = Histogram()
        self.compute_seconds = Histogram()

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
        return "\n".join(lines) + "\n"
