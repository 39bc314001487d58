"""An operator's view of a hanging server (``relight.server.run``): SIGUSR1 writes every thread's stack, SIGUSR2 every
pending asyncio task's, into the server's log; the server keeps serving afterwards."""

from __future__ import annotations

import httpx
import pytest

from .support import start_server, wait_until

pytestmark = pytest.mark.timeout(120)


def test_usr1_and_usr2_dump_stacks_and_the_server_keeps_serving(tmp_path_factory: pytest.TempPathFactory) -> None:
    server = start_server(tmp_path_factory.mktemp("dump"))
    try:
        server.dump_stacks()
        wait_until(lambda: "asyncio tasks" in server.output(), 30, "the asyncio task dump")
        log = server.output()
        assert "Current thread" in log or "Thread 0x" in log, log[-2000:]  # faulthandler's all-thread dump
        assert "serve" in log  # the main thread is inside uvicorn's serve loop
        assert "task relight-health:" in log, log[-2000:]  # the health monitor's task and where it waits
        assert "in _loop" in log
        assert "relight: Dask scheduler" in log and log.count("\nworker tls://") >= 2  # the embedded cluster's
        assert server.alive()
        assert httpx.get(f"{server.url}/health", timeout=30).status_code == 200
    finally:
        server.stop()
