"""
A copy of a robomimic dataset with only what a training config reads: each demo's ``train.dataset_keys`` and the
observations its ``observation.modalities`` name, the file's attributes and masks; no simulator states or model
XML. The GPU machine takes at most 64 MiB of files, and the study's expert.hdf5 (states of every grain) is 215 MB.

    python results/grid_calibrated_diffusion/slim_dataset.py CONFIG.json runs/grid_calibrated/data/expert.hdf5 \
        .gpu/expert_slim.hdf5
"""

from __future__ import annotations

import json
import sys

import h5py

DROPPED_DEMO_ATTRS = ("model_file",)  # a demo's MuJoCo XML: only replay reads it


def slim(source: str, target: str, config: dict) -> int:
    """Writes ``target`` with what robomimic config ``config`` trains on; returns the number of demos copied."""
    fields = config["train"]["dataset_keys"]
    keys = [k for modality in config["observation"]["modalities"]["obs"].values() for k in modality]
    with h5py.File(source, "r") as src, h5py.File(target, "w") as dst:
        data = dst.create_group("data")
        data.attrs.update(src["data"].attrs)
        for name, demo in src["data"].items():
            g = data.create_group(name)
            g.attrs.update({k: v for k, v in demo.attrs.items() if k not in DROPPED_DEMO_ATTRS})
            for field in fields:
                src.copy(demo[field], g, name=field)
            obs = g.create_group("obs")
            for key in keys:
                src.copy(demo["obs"][key], obs, name=key)
        src.copy(src["mask"], dst, name="mask")
        return len(data)


if __name__ == "__main__":
    config_path, source, target = sys.argv[1:4]
    print(f"copied {slim(source, target, json.loads(open(config_path).read()))} demos")
