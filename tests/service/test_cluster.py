"""``relight.server.cluster.Cluster.submit`` accepts only task functions of ``relight.worker``: the server never
submits a core function to Dask directly (the worker's entry points are thin wrappers in ``worker/``)."""

from __future__ import annotations

import types

import pytest

from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.worker import analysis, render, tasks
from relight.worker.progress import run_job


def test_core_functions_are_refused() -> None:
    from relight.gl.views import envmap_texture, reference_sphere_image

    cluster = Cluster(Settings())
    for fn in (reference_sphere_image, envmap_texture, print):
        with pytest.raises(TypeError, match="Dask callables live in worker/"):
            cluster.submit(fn, key="k")
    lookalike = types.FunctionType(run_job.__code__, {}, "run_job")
    lookalike.__module__ = "relight.workers_elsewhere"  # a prefix of the package name is not the package
    with pytest.raises(TypeError, match="relight.workers_elsewhere"):
        cluster.submit(lookalike, key="k")


def test_worker_tasks_pass_the_check() -> None:
    cluster = Cluster(Settings())  # not started: a task that passes the check reaches the (absent) client
    for fn in (run_job, tasks.analyze_envmap, tasks.render_reflection, render.reference_image,
               render.envmap_texture, analysis.calibrate_costmodel):
        with pytest.raises(RuntimeError, match="not started"):
            cluster.submit(fn, key="k")
