"""The settled-pile cache never poisons a run: every malformed entry is refused on load (and settled anew), a folder
that cannot hold the cache turns it off with one warning, and no temporary file outlives a write."""

import errno
import os
import time
import warnings

import numpy as np
import pytest
from helpers.env import make_env

from veragmil_suite.environments import pile_cache, settling

N = 5


@pytest.fixture(autouse=True)
def cache_on(monkeypatch):
    monkeypatch.setattr(pile_cache, "_disabled", None)


def _entry() -> dict:
    rng = np.random.default_rng(0)
    quats = rng.normal(size=(N + 1, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    return dict(
        bowl_qpos=np.r_[rng.normal(size=3), quats[0]],
        grain_qpos=np.c_[rng.normal(size=(N, 3)), quats[1:]],
        max_speed=np.float64(0.001),
        settle_time=np.float64(1.5),
    )


def _malformed():
    """Every way an entry can be wrong, generated from a valid one: a key missing, each array of another shape,
    each value non-finite, text instead of numbers, a quaternion that is not a unit one, a negative time."""
    good = _entry()
    for key in good:
        yield f"no {key}", {k: v for k, v in good.items() if k != key}
    for key, value in good.items():
        shapes = [value.ravel()[:3], value[None], np.zeros((0,))] if value.ndim else [np.array([value, value])]
        shapes += [value.reshape(-1)] if value.ndim > 1 else []
        for i, shape in enumerate(shapes):
            yield f"{key} shape {i}", {**good, key: shape}
        for bad in (np.nan, np.inf, -np.inf):
            broken = np.array(value, dtype=np.float64)
            broken.flat[0] = bad
            yield f"{key} {bad}", {**good, key: broken}
        yield f"{key} text", {**good, key: np.full(np.shape(value), "x")}
    yield "bowl quaternion", {**good, "bowl_qpos": np.r_[good["bowl_qpos"][:3], 2.0, 0, 0, 0]}
    yield "grain quaternion", {**good, "grain_qpos": np.c_[good["grain_qpos"][:, :3], np.zeros((N, 4))]}
    yield "negative time", {**good, "settle_time": np.float64(-1.0)}


def test_a_valid_entry_loads_as_it_was_saved(tmp_path):
    entry = _entry()
    path = tmp_path / "key.npz"
    pile_cache.save(path, entry["bowl_qpos"], entry["grain_qpos"], float(entry["max_speed"]), 1.5)
    bowl, grains, speed, duration = pile_cache.load(path, N)
    np.testing.assert_array_equal(bowl, entry["bowl_qpos"])
    np.testing.assert_array_equal(grains, entry["grain_qpos"])
    assert (speed, duration) == (0.001, 1.5)
    assert pile_cache.load(path, N + 1) is None  # a pile of another size: settled anew
    assert sorted(p.name for p in tmp_path.iterdir()) == ["key.npz"]


@pytest.mark.parametrize("what, entry", list(_malformed()), ids=lambda x: x if isinstance(x, str) else "")
def test_every_malformed_entry_is_refused_on_load(tmp_path, what, entry):
    path = tmp_path / "key.npz"
    np.savez(path, **entry)
    assert pile_cache.load(path, N) is None


@pytest.mark.parametrize("poison", ["bowl_qpos of shape (3,)", "NaN in bowl_qpos"])
def test_a_poisoned_entry_is_settled_again_and_replaced(tmp_path, monkeypatch, poison):
    """The two entries that broke every make (a (3,) bowl pose) or ended every episode at step 1 (a NaN)."""
    monkeypatch.setenv("VERAGMIL_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(settling, "_MEMORY", {})
    make_env("pasta", n_grains=12, pile_variants=1).close()
    (cached,) = tmp_path.glob("*.npz")
    entry = dict(np.load(cached))
    if poison.startswith("NaN"):
        entry["bowl_qpos"][0] = np.nan
    else:
        entry["bowl_qpos"] = entry["bowl_qpos"][:3]
    np.savez(cached, **entry)
    monkeypatch.setattr(settling, "_MEMORY", {})
    env = make_env("pasta", n_grains=12, pile_variants=1)
    env.reset()
    for _ in range(5):
        _, _, _, info = env.step(np.zeros(6))
        assert info["physics_error"] == ""
    env.close()
    with np.load(cached) as f:  # rebuilt: the next run reads a valid entry
        assert f["bowl_qpos"].shape == (7,) and np.isfinite(f["bowl_qpos"]).all()
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".npz"]


def _warnings_of(action) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        action()
    return [str(w.message) for w in caught if "settled-pile cache off" in str(w.message)]


def test_a_cache_folder_that_is_a_file_turns_the_cache_off_with_one_warning(tmp_path, monkeypatch):
    folder = tmp_path / "piles"
    folder.write_text("not a folder")
    monkeypatch.setenv("VERAGMIL_CACHE_DIR", str(folder))
    monkeypatch.setattr(settling, "_MEMORY", {})

    def run():
        for food in ("pasta", "peas"):  # two piles, two saves: one warning
            env = make_env(food, n_grains=12, pile_variants=1)
            env.reset()
            assert env.step(np.zeros(6))[3]["physics_error"] == ""
            env.close()

    said = _warnings_of(run)
    assert len(said) == 1 and "it is a file, not a folder" in said[0]
    assert folder.read_text() == "not a folder"


@pytest.mark.parametrize("code", [errno.EROFS, errno.ENOSPC, errno.EACCES])
def test_an_unwritable_cache_turns_the_cache_off_and_leaves_no_temporary_file(tmp_path, monkeypatch, code):
    entry = _entry()
    real = np.savez

    def refused(file, **arrays):
        real(file, **arrays)  # part of the entry is written when the disk refuses the rest
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(np, "savez", refused)
    said = _warnings_of(
        lambda: [
            pile_cache.save(tmp_path / f"{i}.npz", entry["bowl_qpos"], entry["grain_qpos"], 0.001, 1.5)
            for i in range(2)
        ]
    )
    assert len(said) == 1 and os.strerror(code) in said[0]
    assert list(tmp_path.iterdir()) == []
    assert pile_cache.load(tmp_path / "0.npz", N) is None


def test_a_killed_writers_temporary_file_is_removed_by_the_next_write(tmp_path):
    entry = _entry()
    stale, fresh = tmp_path / ".a.123.tmp.npz", tmp_path / ".b.456.tmp.npz"
    for path in (stale, fresh):
        path.write_bytes(b"half an entry")
    old = time.time() - 2 * pile_cache.STALE_TMP_S
    os.utime(stale, (old, old))
    pile_cache.save(tmp_path / "key.npz", entry["bowl_qpos"], entry["grain_qpos"], 0.001, 1.5)
    assert sorted(p.name for p in tmp_path.iterdir()) == [fresh.name, "key.npz"]  # a live writer's is left alone
