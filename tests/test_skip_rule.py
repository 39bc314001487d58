"""tests/conftest.py's rule, run on a throw-away suite: skips fail, xfails and passes do not."""

from __future__ import annotations

from pathlib import Path

import pytest


def test_skips_fail_and_xfail_does_not(pytester: pytest.Pytester) -> None:
    pytester.makeconftest((Path(__file__).parent / "conftest.py").read_text().replace(
        'pytest_plugins = ["pytester"]', ""))
    pytester.makepyfile(test_demo="""
        import pytest

        def test_skipped():
            pytest.skip("demo reason")

        @pytest.mark.skipif(True, reason="marker reason")
        def test_marked():
            pass

        @pytest.mark.xfail(reason="known")
        def test_xfailed():
            assert False

        def test_passes():
            pass
    """)
    result = pytester.runpytest("-q")
    # pytest.skip() in the body fails the call; a skipif marker skips in set-up, which now errors.
    result.assert_outcomes(passed=1, failed=1, errors=1, xfailed=1)
    result.stdout.fnmatch_lines(["*demo reason*"])


def test_module_level_importorskip_fails(pytester: pytest.Pytester) -> None:
    pytester.makeconftest((Path(__file__).parent / "conftest.py").read_text().replace(
        'pytest_plugins = ["pytester"]', ""))
    pytester.makepyfile(test_mod="""
        import pytest
        pytest.importorskip("relight_no_such_module")

        def test_never():
            pass
    """)
    result = pytester.runpytest("-q")
    assert result.ret != 0
    result.stdout.fnmatch_lines(["*skipped module fails this suite*"])
