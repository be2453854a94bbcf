"""
A copy of a robomimic dataset with only what training reads: each demo's actions, rewards, dones and the low-dim
observations of one observation set, the file's attributes and masks; no simulator states or model XML. The GPU
machine takes at most 64 MiB of files, and the study's expert.hdf5 (states of every grain) is 215 MB.

    python results/grid_calibrated_diffusion/slim_dataset.py runs/grid_calibrated/data/expert.hdf5 .gpu/expert_slim.hdf5
"""

from __future__ import annotations

import sys

import h5py

from veragmil_suite.learning.observation_sets import DEFAULT_OBSERVATION_SET, OBSERVATION_SETS

DROPPED_DEMO_ATTRS = ("model_file",)  # a demo's MuJoCo XML: only replay reads it


def slim(source: str, target: str, obs_set: str = DEFAULT_OBSERVATION_SET) -> int:
    """Writes ``target``; returns the number of demos copied."""
    keys = OBSERVATION_SETS[obs_set]
    with h5py.File(source, "r") as src, h5py.File(target, "w") as dst:
        data = dst.create_group("data")
        data.attrs.update(src["data"].attrs)
        for name, demo in src["data"].items():
            g = data.create_group(name)
            g.attrs.update({k: v for k, v in demo.attrs.items() if k not in DROPPED_DEMO_ATTRS})
            for field in ("actions", "rewards", "dones"):
                src.copy(demo[field], g, name=field)
            obs = g.create_group("obs")
            for key in keys:
                src.copy(demo["obs"][key], obs, name=key)
        src.copy(src["mask"], dst, name="mask")
        return len(data)


if __name__ == "__main__":
    print(f"copied {slim(*sys.argv[1:3])} demos")
