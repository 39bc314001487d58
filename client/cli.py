"""Client subcommands of the ``relight`` CLI (registered through the ``relight.commands`` entry point group;
``relight serve`` and ``relight worker`` register from ``relight.server.cli`` and ``relight.worker.cli``).

    relight upload ENVMAP [--server URL]
    relight submit ENVMAP --brdf SPEC [--epsilon E | --order F] [--size S] [--sun extract|clamp=V|keep] [--wait]
                   [--out SHRM.exr]
    relight jobs [--state S]
    relight plan ENVMAP --brdf SPEC [--epsilon E | --order F] [--p-order P] [--size S] [--sun extract|clamp=V|keep]
        what POST /shrms would do: representation, orders, predicted error and seconds; with --sun extract and a
        tolerance each lobe's order with and without the sun and the factor

``--server`` defaults to ``$RELIGHT_SERVER`` or http://127.0.0.1:8000; ``--api-key`` to ``$RELIGHT_API_KEY``.
The SDK (httpx, pydantic) loads when a command runs; a :class:`relight.client.errors.RelightError` is printed on one
line with exit status 2, like the core's errors.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

_DIGEST = re.compile(r"^[0-9a-f]{64}$")


def _client(args: argparse.Namespace) -> Any:
    from relight.client.sdk import RelightClient

    return RelightClient(args.server, api_key=args.api_key, timeout=args.timeout)


def _add_job_args(p: argparse.ArgumentParser) -> None:
    """The map, BRDF and order arguments `submit` and `plan` share."""
    p.add_argument("envmap", help="a file (uploaded first) or an environment-map id")
    p.add_argument("--brdf", required=True, help="phong:s=32, a JSON spec file, or a BRDF id")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--epsilon", type=float)
    g.add_argument("--order", type=int)
    p.add_argument("--p-order", type=int, help="view order P for SHRMs (with --order)")
    p.add_argument("--size", type=int)


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--server", default=os.environ.get("RELIGHT_SERVER", "http://127.0.0.1:8000"),
                   help="service URL (default $RELIGHT_SERVER or http://127.0.0.1:8000)")
    p.add_argument("--api-key", default=os.environ.get("RELIGHT_API_KEY"), help="default $RELIGHT_API_KEY")
    p.add_argument("--timeout", type=float, default=120.0, help="seconds per HTTP request")
    p.add_argument("--json", action="store_true", help="print JSON")


# -------------------------------------------------------------------------------------------------- commands
def cmd_upload(args: argparse.Namespace) -> int:
    with _client(args) as c:
        env = c.upload_envmap(args.envmap, name=args.name)
    if args.json:
        print(env.model_dump_json(indent=2))
    else:
        print(f"{env.id}  {env.width}x{env.height} {env.format}  max {max(env.max):.4g}  "
              f"negatives clamped {env.negatives_clamped}")
    return 0


def _brdf_arg(text: str) -> Any:
    p = Path(text)
    if text.endswith(".json") and p.is_file():
        return json.loads(p.read_text())
    return text


def cmd_submit(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with _client(args) as c:
        envmap = _envmap_id(c, args.envmap)
        job = c.submit(envmap, _brdf_arg(args.brdf), epsilon=args.epsilon, order=args.order, p_order=args.p_order,
                       size=args.size, sun=None if args.sun == "keep" else args.sun)
        if not (args.wait or args.out):
            print(job.model_dump_json(indent=2) if args.json else f"{job.id}  {job.state}")
            return 0
        if not job.state.terminal:
            with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                          TimeElapsedColumn(), transient=True) as bar:
                task = bar.add_task(f"job {job.id[:12]} queued", total=1.0)

                def update(j: Any) -> None:
                    bar.update(task, completed=j.progress, description=f"job {j.id[:12]} {j.state}: {j.stage or ''}")

                job = c.wait(job.id, timeout=args.wait_timeout, on_update=update)
        elif job.state != "succeeded":
            from relight.client.errors import JobFailed

            raise JobFailed(job)
        if args.out:
            name = "coefficients.bin" if args.out.endswith(".bin") else "coefficients.exr"
            Path(args.out).write_bytes(c.download(job.id, name))
        if args.json:
            print(job.model_dump_json(indent=2))
        else:
            m = job.measured
            took = f"{m.seconds:.3f} s" if m and m.seconds is not None else "cached"
            rms = f", predicted relative RMS {m.rms_error:.3g}" if m and m.rms_error is not None else ""
            print(f"{job.id}  {job.state} ({took}{rms})" + (f"  -> {args.out}" if args.out else ""))
    return 0


def _envmap_id(c: Any, text: str) -> str:
    return text if _DIGEST.match(text) and not Path(text).exists() else str(c.upload_envmap(text).id)


def cmd_plan(args: argparse.Namespace) -> int:
    with _client(args) as c:
        plan = c.plan(_envmap_id(c, args.envmap), _brdf_arg(args.brdf), epsilon=args.epsilon, order=args.order,
                      p_order=args.p_order, size=args.size, sun=None if args.sun == "keep" else args.sun)
    if args.json:
        print(plan.model_dump_json(indent=2))
        return 0
    o, e = plan.orders, plan.predicted_error
    rms = e.rms_appendix_b if e.rms_appendix_b is not None else e.rms_min_of_errors
    print(f"{plan.job_id}  {plan.representation}  F_B = {o.F_B}  P_B = {o.P_B}  "
          f"{plan.output.height}x{plan.output.width}x{plan.output.layers}  predicted {plan.predicted_seconds:.3g} s"
          + (f", relative RMS <= {rms:.3g}" if rms is not None else "") + ("  (cached)" if plan.cached else ""))
    if plan.sun is not None:
        sun = plan.sun.extracted
        print(f"sun: direction {', '.join(f'{x:.4f}' for x in sun['direction'])}, illuminance "
              f"{sun['illuminance']:.4g}, {100 * sun['energy_fraction']:.1f} % of the map's energy")
        for lobe in plan.sun.lobes:
            def order(f: int, met: bool) -> str:
                return str(f) if met else f"{f} (epsilon not met below F_B)"

            print(f"  {lobe.kind} ({lobe.center}-centred): order {order(lobe.order_with_sun, lobe.met_with_sun)} "
                  f"with the sun, {order(lobe.order_without_sun, lobe.met_without_sun)} without: "
                  f"{lobe.factor:.2f}x lower at epsilon = {plan.sun.epsilon:g} (the residual held to its own "
                  f"energy: {order(lobe.order_residual_alone, lobe.met_residual_alone)})")
    return 0


def cmd_jobs(args: argparse.Namespace) -> int:
    with _client(args) as c:
        jobs = c.list_jobs(args.state, args.limit)
    if args.json:
        print(json.dumps([j.model_dump(mode="json") for j in jobs], indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table("id", "kind", "state", "stage", "progress", "brdf", "created")
    for j in jobs:
        table.add_row(j.id[:16], j.kind, j.state.value, j.stage or "", f"{100 * j.progress:.0f}%",
                      str((j.brdf_spec or {}).get("kind", "")), j.created_at.strftime("%Y-%m-%d %H:%M:%S"))
    Console().print(table)
    return 0


def _guard(fn: Any) -> Any:
    """Client errors print on one line with exit status 2 (as ``relight.cli`` prints the core's); ^C is 130."""

    def run(args: argparse.Namespace) -> int:
        from relight.client.errors import RelightError

        try:
            code: int = fn(args)
            return code
        except RelightError as exc:
            print(f"relight: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            return 130

    return run


def register(sub: Any) -> None:
    """Add ``upload``, ``submit``, ``plan`` and ``jobs`` to the ``relight`` command's subparsers."""
    p = sub.add_parser("upload", help="upload an environment map to the service")
    p.add_argument("envmap")
    p.add_argument("--name")
    _add_common(p)
    p.set_defaults(func=_guard(cmd_upload))

    p = sub.add_parser("submit", help="submit a prefiltering job to the service")
    _add_job_args(p)
    p.add_argument("--sun", default="keep", help="extract (prefilter without the sun; the result's input.sun holds "
                   "it), clamp=V or keep (default)")
    p.add_argument("--wait", action="store_true", help="follow progress until the job ends")
    p.add_argument("--wait-timeout", type=float, default=None)
    p.add_argument("--out", help="download the result here (.exr: coefficients.exr, .bin: float16 texture)")
    _add_common(p)
    p.set_defaults(func=_guard(cmd_submit))

    p = sub.add_parser("plan", help="plan a prefiltering job on the service without computing it")
    _add_job_args(p)
    p.add_argument("--sun", default="keep", help="extract (with --epsilon: each lobe's order with and without the "
                   "sun), clamp=V or keep (default)")
    _add_common(p)
    p.set_defaults(func=_guard(cmd_plan))

    p = sub.add_parser("jobs", help="list jobs on the service")
    p.add_argument("--state", choices=["queued", "running", "succeeded", "failed", "cancelled"])
    p.add_argument("--limit", type=int, default=50)
    _add_common(p)
    p.set_defaults(func=_guard(cmd_jobs))
