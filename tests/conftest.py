"""Suite-wide rule: a skipped test is a failed test.

CI runs everything (``make test``); a dependency that is missing must be installed by ``make test``, not skipped
around, and a case that "cannot happen" is asserted. This hook turns every skip (``pytest.skip``,
``importorskip``, ``skipif``) into a failure that names the reason, except for the node ids in
:data:`ALLOWED_SKIPS` (empty: add one only with a reason a reviewer accepts). ``xfail`` is not a skip and is
left alone.
"""

from __future__ import annotations

from collections.abc import Generator

import pytest

pytest_plugins = ["pytester"]

#: node id -> why skipping it is acceptable. Empty on purpose.
ALLOWED_SKIPS: dict[str, str] = {}


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, None, None]:
    outcome = yield
    report = outcome.get_result()
    if report.skipped and not hasattr(report, "wasxfail") and item.nodeid not in ALLOWED_SKIPS:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = (f"skipped tests fail this suite (tests/conftest.py): {reason}\n"
                           "install the dependency through `make test`, or assert what cannot happen")


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, None, None]:
    """A module that skips while being collected (``importorskip`` at module level) fails the same way."""
    outcome = yield
    report = outcome.get_result()
    if report.skipped and collector.nodeid not in ALLOWED_SKIPS:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped module fails this suite (tests/conftest.py): {reason}"
