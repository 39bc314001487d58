"""The garbage-collector pause histogram of ``/metrics`` (:class:`relight.server.services.metrics.GcPauses`)."""

from __future__ import annotations

import gc
import re

from relight.server.services.metrics import GcPauses, Metrics


def _count(text: str, generation: int) -> int:
    m = re.search(rf'^relight_gc_pause_seconds_count{{generation="{generation}"}} (\d+)$', text, re.M)
    assert m is not None, text
    return int(m[1])


def test_every_collection_is_counted_in_its_generation_while_started() -> None:
    metrics = Metrics()
    before = _count(metrics.render({}, 0), 2)
    assert before == 0
    metrics.gc.start()
    try:
        gc.collect()  # one full collection (generation 2), however many the interpreter ran meanwhile
        gc.collect()
        text = metrics.render({}, 0)
    finally:
        metrics.gc.stop()
    assert _count(text, 2) >= 2
    pauses = metrics.gc.by_generation[2]
    assert pauses.total > 0 and sum(pauses.counts) == pauses.n
    # the buckets are cumulative and end at the count
    buckets = [int(m[1]) for m in re.finditer(r'^relight_gc_pause_seconds_bucket\{generation="2",le="[^"]+"\} (\d+)$',
                                              text, re.M)]
    assert buckets == sorted(buckets) and buckets[-1] == _count(text, 2)
    stopped = pauses.n
    gc.collect()
    assert metrics.gc.by_generation[2].n == stopped  # stop() removed the callback
    assert metrics.gc._callback not in gc.callbacks  # noqa: SLF001


def test_start_twice_registers_once() -> None:
    pauses = GcPauses()
    pauses.start()
    pauses.start()
    try:
        assert gc.callbacks.count(pauses._callback) == 1  # noqa: SLF001
    finally:
        pauses.stop()
    assert pauses._callback not in gc.callbacks  # noqa: SLF001
