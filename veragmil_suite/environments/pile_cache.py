"""The disk cache of settled piles (veragmil_suite.environments.settling): one ``<key>.npz`` per pile, checked when
read.

An entry is used only when it holds a pile of the expected form: the bowl's pose (7,), every grain's pose (n, 7),
finite, with unit quaternions, and two finite scalars. Any other (truncated, foreign, of another shape, NaN) is
settled anew and overwritten. A folder that cannot hold the cache (a file, read-only, full) turns the disk cache
off for this process, said once as a warning: the run goes on with its piles in memory. An entry is written to a
temporary file beside it and renamed into place, and no temporary file outlives the write (those of killed
writers are removed by the next one).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np

TMP_SUFFIX = ".tmp.npz"
STALE_TMP_S = 600.0  # a temporary entry this old belongs to a killed writer
_QUAT_TOLERANCE = 1e-3

_disabled: str | None = None  # why the disk cache is off in this process (said once)


def load(path: Path, n_grains: int) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """The entry at ``path`` as (bowl_qpos, grain_qpos, max_speed, settle_time) when it is a valid pile of
    ``n_grains`` grains; None when it is missing, unreadable or invalid (to be settled anew) or the cache is off."""
    if _disabled is not None:
        return None
    try:
        with np.load(path, allow_pickle=False) as f:
            bowl, grains = np.asarray(f["bowl_qpos"]), np.asarray(f["grain_qpos"])
            speed, duration = np.asarray(f["max_speed"]), np.asarray(f["settle_time"])
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None  # truncated, foreign or damaged
    if not _valid(bowl, grains, speed, duration, n_grains):
        return None
    return bowl.astype(np.float64), grains.astype(np.float64), float(speed), float(duration)


def _valid(bowl: np.ndarray, grains: np.ndarray, speed: np.ndarray, duration: np.ndarray, n_grains: int) -> bool:
    if bowl.shape != (7,) or grains.shape != (n_grains, 7) or speed.shape != () or duration.shape != ():
        return False
    values = (bowl, grains, speed, duration)
    if not all(np.issubdtype(v.dtype, np.floating) and np.isfinite(v).all() for v in values):
        return False
    quats = np.vstack([bowl[3:], grains[:, 3:]])
    return bool(np.all(np.abs(np.linalg.norm(quats, axis=1) - 1.0) < _QUAT_TOLERANCE)) and float(duration) >= 0


def save(path: Path, bowl_qpos: np.ndarray, grain_qpos: np.ndarray, max_speed: float, settle_time: float) -> None:
    """Write the entry at ``path`` atomically (parallel workers never read half a file); a folder that cannot
    take it turns the disk cache off, with one warning."""
    if _disabled is not None:
        return
    folder = path.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
        _remove_stale(folder)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.stem}.", suffix=TMP_SUFFIX)
    except OSError as e:
        reason = "it is a file, not a folder" if folder.is_file() else (e.strerror or str(e))
        disable(f"cannot write in {folder} ({reason})")
        return
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, bowl_qpos=bowl_qpos, grain_qpos=grain_qpos, max_speed=max_speed, settle_time=settle_time)
        os.replace(tmp, path)
    except OSError as e:
        disable(f"cannot write {path} ({e.strerror or e})")
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def _remove_stale(folder: Path) -> None:
    """Temporary entries of writers killed mid-write (older than STALE_TMP_S: a live write takes milliseconds)."""
    now = time.time()
    for tmp in folder.glob(f"*{TMP_SUFFIX}"):
        with contextlib.suppress(OSError):
            if now - tmp.stat().st_mtime > STALE_TMP_S:
                tmp.unlink()


def disable(reason: str) -> None:
    """Turn the disk cache off for this process, warning once why."""
    global _disabled
    if _disabled is None:
        _disabled = reason
        warnings.warn(
            f"settled-pile cache off: {reason}; piles are settled in memory for this run "
            "(set VERAGMIL_CACHE_DIR to a writable folder to keep them)",
            RuntimeWarning,
            stacklevel=3,
        )


def enable() -> None:
    """Turn the disk cache back on (after the folder was fixed, or in tests)."""
    global _disabled
    _disabled = None
