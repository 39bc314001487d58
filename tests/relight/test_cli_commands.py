"""How the ``relight`` command is assembled: the core's subcommands, the core providers of
``relight.cli.COMMAND_PROVIDERS``, and the ``relight.commands`` entry points of the service packages. The command
names and flags are a contract (README, docker/, external scripts), so they are pinned here."""

from __future__ import annotations

import argparse
import subprocess
import sys
import types
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pytest

from relight import cli

#: Entry points of pyproject.toml [project.entry-points."relight.commands"]: each package registers its own.
ENTRY_POINTS = {
    "client": "relight.client.cli:register",
    "serve": "relight.server.cli:register",
    "worker": "relight.worker.cli:register",
}

#: The service commands' options, as they were when client/cli.py registered all of them.
SERVICE_OPTIONS = {
    "serve": {"--host", "--port", "--data", "--workers", "--scheduler", "--preload", "--no-preload"},
    "worker": {"--scheduler", "--nthreads", "--name", "--memory-limit", "--host", "--no-nanny", "--tls-ca-file",
               "--tls-cert", "--tls-key"},
    # issue 12, item 7: the scale-out cluster on TLS (docker/compose.yaml runs these)
    "scheduler": {"--host", "--port", "--tls-ca-file", "--tls-cert", "--tls-key"},
    "upload": {"--name", "--server", "--api-key", "--timeout", "--json"},
    "submit": {"--brdf", "--epsilon", "--order", "--p-order", "--size", "--wait", "--wait-timeout", "--out",
               "--server", "--api-key", "--timeout", "--json", "--sun"},
    "jobs": {"--state", "--limit", "--server", "--api-key", "--timeout", "--json"},
    # issue 17, item 6: the plan with --sun extract shows each lobe's order with and without the sun
    "plan": {"--brdf", "--epsilon", "--order", "--p-order", "--size", "--sun", "--server", "--api-key", "--timeout",
             "--json"},
}


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions for s in a.option_strings if s not in ("-h", "--help")}


def test_entry_points_are_installed_as_declared() -> None:
    got = {ep.name: ep.value for ep in entry_points(group=cli.ENTRY_POINT_GROUP)}
    assert got == ENTRY_POINTS


def test_core_providers_name_only_core_modules() -> None:
    assert all(name.startswith("relight.") and name.count(".") == 1 for name in cli.COMMAND_PROVIDERS)
    assert not any(name.split(".")[1] in ("server", "worker", "client", "contract") for name in cli.COMMAND_PROVIDERS)


def test_service_commands_keep_their_names_and_flags() -> None:
    subs = _subparsers(cli.build_parser())
    for name, options in SERVICE_OPTIONS.items():
        assert _options(subs[name]) == options, name
    core = {"prefilter", "reference", "compare", "info", "reflect", "render", "tradeoff", "scene", "costmodel"}
    assert core | set(SERVICE_OPTIONS) <= set(subs)


def test_a_name_added_to_command_providers_is_registered(monkeypatch: pytest.MonkeyPatch) -> None:
    """What a rebase that appends a core provider relies on."""
    mod = types.ModuleType("relight._test_provider")

    def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
        p = sub.add_parser("probe-command")
        p.set_defaults(func=lambda args: 7)

    mod.register = register  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "relight._test_provider", mod)
    monkeypatch.setattr(cli, "COMMAND_PROVIDERS", [*cli.COMMAND_PROVIDERS, "relight._test_provider"])
    assert cli.main(["probe-command"]) == 7


def test_registering_commands_loads_no_service_library() -> None:
    """Building the whole parser (what every ``relight`` run does) imports no web, HTTP or Dask library: they load
    when a service command runs (bench/startup.py measures what this saves)."""
    heavy = ("fastapi", "starlette", "uvicorn", "httpx", "distributed", "dask", "sqlalchemy", "pydantic", "rich",
             "moderngl")
    code = ("import sys; from relight import cli; cli.build_parser(); "
            f"print(' '.join(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"loaded while registering commands: {out}"


def test_a_core_command_loads_no_other_command(tmp_path: Path) -> None:
    """``relight prefilter`` on an EXR imports neither the other commands' modules nor what only they need (SciPy,
    Pillow, the service libraries): what keeps a small job's process near its import floor (bench/startup.py)."""
    from relight.envmap.exr import write_exr

    src = tmp_path / "sky.exr"
    rng = np.random.default_rng(3)
    write_exr(src, (0.5 + rng.random((16, 32, 3))).astype(np.float32))
    code = ("import sys; from relight import cli; "
            f"code = cli.main(['prefilter', {str(src)!r}, '--brdf', 'phong:s=8', '--epsilon', '0.05', "
            f"'--out', {str(tmp_path / 'out.exr')!r}]); "
            "mods = ('scipy', 'PIL', 'httpx', 'pydantic', 'fastapi', 'distributed', 'relight.cli_shrm', "
            "'relight.cli_plan', 'relight.client', 'relight.server', 'relight.worker', 'relight.mesh'); "
            "print(code, ' '.join(m for m in mods if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    status, *loaded = out.strip().splitlines()[-1].split(" ")
    assert status == "0"
    assert loaded == [], f"relight prefilter loaded {loaded}"
