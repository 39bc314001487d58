"""Where calibrations live: a JSON file per machine and relight version in the user's cache folder, and an in-memory
copy per process (:func:`load_calibration`)."""

from __future__ import annotations

import json
import os
import tempfile
import threading
from pathlib import Path

import relight
from relight.costmodel import calibration as _calibration
from relight.costmodel.calibration import Calibration, calibration_key, default_calibration


def cache_dir() -> Path:
    """``$RELIGHT_CACHE_DIR``, else ``$XDG_CACHE_HOME/relight``, else ``~/.cache/relight``."""
    env = os.environ.get("RELIGHT_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "relight"


def cache_path(directory: Path | None = None, key: str | None = None) -> Path:
    k = key or calibration_key()
    return (directory or cache_dir()) / f"costmodel-{relight.__version__}-{k[:16]}.json"


def save_calibration(cal: Calibration, path: Path) -> None:
    """Write atomically (a temporary file in the same folder, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".costmodel-", suffix=".json", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(cal.as_dict(), fh, indent=1, sort_keys=True)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


_memo: dict[str, Calibration] = {}
_lock = threading.Lock()


def load_calibration(
    directory: Path | None = None, *, run: bool = True, recalibrate: bool = False, quick: bool = False
) -> Calibration:
    """The calibration for this machine and relight version: from memory, else the cache file, else (``run``)
    a fresh :func:`calibrate` saved to the cache, else :func:`default_calibration`.

    Thread-safe: concurrent callers wait for one calibration. An unreadable cache file is replaced.
    """
    key = calibration_key()
    path = cache_path(directory, key)
    memo_key = str(path)
    with _lock:
        if not recalibrate and memo_key in _memo:
            return _memo[memo_key]
        if not recalibrate and path.is_file():
            try:
                cal = Calibration.from_dict(json.loads(path.read_text(encoding="utf-8")))
                if cal.key == key:
                    _memo[memo_key] = cal
                    return cal
            except (OSError, ValueError):
                pass  # unreadable or foreign: calibrate again
        if not run and not recalibrate:
            return default_calibration()
        cal = _calibration.calibrate(quick=quick)
        try:
            save_calibration(cal, path)
        except OSError:
            pass  # a read-only cache folder: keep the calibration in memory only
        _memo[memo_key] = cal
        return cal


def forget() -> None:
    """Drop the in-memory calibrations (tests)."""
    with _lock:
        _memo.clear()
