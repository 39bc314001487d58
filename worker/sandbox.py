"""A bounded pool of sandbox processes for computations the API answers synchronously (``/plan``'s order search and
BRDF coefficients): the API process itself never computes.

Each sandbox is a spawned process (no fork of the threaded server) under an address-space limit
(``RLIMIT_AS``): an allocation beyond it raises ``MemoryError`` there, never in the server. A call that runs past
its time limit, or whose caller is cancelled (the client went away), kills its sandbox; a fresh one replaces it, so
abandoned work stops at once. At most ``size`` computations run at a time; the rest wait for a free sandbox, so a
flood of expensive requests queues here instead of taking the server's threads.
"""

from __future__ import annotations

import asyncio
import contextlib
import multiprocessing
import resource
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, TypeVar

T = TypeVar("T")


def busy_then(busy_s: float, fn: Callable[..., T], *args: Any) -> T:
    """``fn(*args)`` after ``busy_s`` seconds of CPU work: the server's test hook ``plan_test_busy_s`` (0 in
    production), because real plans now finish in about a second, too fast for a test to catch one in flight."""
    end = time.process_time() + busy_s
    spin = 0
    while time.process_time() < end:
        spin += 1
    return fn(*args)


class SandboxMemoryError(Exception):
    """The computation needed more memory than the sandbox's limit."""


class SandboxTimeout(Exception):
    """The computation ran past its time limit; its sandbox was killed."""


def _serve(conn: Connection, memory_bytes: int) -> None:
    """The sandbox's loop: receive ``(fn, args)``, send ``("ok", result)``, ``("memory", None)`` or
    ``("error", exception)``."""
    resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    while True:
        try:
            fn, args = conn.recv()
        except (EOFError, OSError):
            return
        try:
            reply: tuple[str, Any] = ("ok", fn(*args))
        except MemoryError:
            reply = ("memory", None)
        except Exception as exc:  # noqa: BLE001 - handed back to the caller, who decides what it means
            reply = ("error", exc)
        try:
            conn.send(reply)
        except Exception as exc:  # noqa: BLE001 - an unpicklable result or exception: say what it was
            conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))


class _Sandbox:
    def __init__(self, memory_bytes: int) -> None:
        ctx = multiprocessing.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, memory_bytes), daemon=True, name="relight-sandbox")
        self.proc.start()
        child.close()

    def kill(self) -> None:
        with contextlib.suppress(OSError):
            self.conn.close()
        self.proc.kill()
        self.proc.join(5)


class SandboxPool:
    """``size`` sandboxes of ``memory_bytes`` each (module docstring); started lazily, one per concurrent call."""

    def __init__(self, size: int, memory_bytes: int) -> None:
        self.size = size
        self.memory_bytes = memory_bytes
        self._idle: list[_Sandbox] = []
        self._slots = asyncio.Semaphore(size)
        self._closed = False

    @property
    def busy(self) -> int:
        return self.size - self._slots._value  # noqa: SLF001 - the count asyncio keeps anyway

    async def run(self, fn: Callable[..., T], *args: Any, timeout: float) -> T:
        """``fn(*args)`` in a sandbox; raises what ``fn`` raised, :class:`SandboxMemoryError` or
        :class:`SandboxTimeout`. Cancelling the caller kills the sandbox."""
        async with self._slots:
            if self._closed:
                raise RuntimeError("the sandbox pool is closed")
            box = self._idle.pop() if self._idle else _Sandbox(self.memory_bytes)
            loop = asyncio.get_running_loop()
            ready = loop.create_future()
            fd = box.conn.fileno()

            def readable() -> None:
                if not ready.done():
                    ready.set_result(None)

            loop.add_reader(fd, readable)
            healthy = False
            try:
                box.conn.send((fn, args))
                try:
                    await asyncio.wait_for(ready, timeout)
                except TimeoutError:
                    raise SandboxTimeout(f"the computation took longer than {timeout:g} s and was stopped") from None
                try:
                    status, value = box.conn.recv()
                except (EOFError, OSError):  # the process died (killed by the kernel, a crash in C)
                    raise SandboxMemoryError("the computation's process died (over its memory limit?)") from None
                healthy = True
            finally:
                loop.remove_reader(fd)
                if healthy and not self._closed:
                    self._idle.append(box)
                else:
                    box.kill()
        if status == "memory":
            raise SandboxMemoryError(f"the computation needs more than {self.memory_bytes} bytes of memory")
        if status == "error":
            raise value
        result: T = value
        return result

    def close(self) -> None:
        self._closed = True
        while self._idle:
            self._idle.pop().kill()
