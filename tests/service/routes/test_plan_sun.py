"""``POST /plan`` with ``sun=extract`` (issue 17, item 6: "the plan shows the order reduction it buys"): per lobe the
order with and without the sun and the factor, the same numbers as the core's planner on the stored map, in the
SDK and in ``relight plan``'s output; a map without a sun is a 422 naming it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from relight.client.sdk import RelightClient
from relight.planning.sun_orders import plan_job_with_sun

from ..support import Server, assert_healthy, assert_problem

pytestmark = pytest.mark.timeout(600)
CITY = Path(__file__).resolve().parents[3] / "data" / "envmaps" / "city.exr"
MICROFACET = {"kind": "microfacet", "sigma": 0.2}


def test_plan_shows_the_order_the_sun_costs(client: RelightClient, http: httpx.Client, server: Server) -> None:
    env = client.upload_envmap(CITY)
    body = {"envmap": env.id, "brdf": MICROFACET, "epsilon": 1e-2}
    plain = http.post("/plan", json=body)
    assert plain.status_code == 200, plain.text
    assert plain.json().get("sun") is None
    plan = client.plan(env.id, MICROFACET, epsilon=1e-2, sun="extract")
    assert plan.sun is not None and plan.sun.epsilon == 1e-2
    assert plan.job_id != plain.json()["job_id"]  # the job with sun=extract is another job
    # the core's planner on the same stored record and file gives the same orders
    info = http.get(f"/envmaps/{env.id}").json()
    core = plan_job_with_sun(info, MICROFACET, {"epsilon": 1e-2, "sun": "extract"}, CITY)
    assert core.sun is not None
    assert [lobe.model_dump() for lobe in plan.sun.lobes] == core.sun["lobes"]
    (lobe,) = plan.sun.lobes
    assert lobe.F_B == plan.orders.F_B and lobe.order_without_sun < lobe.order_with_sun
    assert plan.sun.extracted["direction"] == core.sun["extracted"]["direction"]
    # relight plan prints it
    out = subprocess.run([sys.executable, "-m", "relight.cli", "plan", env.id, "--brdf", "microfacet:sigma=0.2",
                          "--epsilon", "0.01", "--sun", "extract", "--server", server.url],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert (f"order {lobe.order_with_sun}" in out.stdout and f"{lobe.order_without_sun} without"
            in out.stdout and f"{lobe.factor:.2f}x lower" in out.stdout), out.stdout
    # a map without a sun: 422 naming it, and the plan service keeps serving
    flat = client.upload_envmap(CITY.parent / "courtyard.exr")  # brightest pixel 69 x the mean: no sun
    assert_problem(http.post("/plan", json={**body, "envmap": flat.id, "sun": "extract"}), 422, "no sun")
    assert_problem(http.post("/plan", json={**body, "sun": "remove"}), 422, "sun")
    assert_healthy(http)
