"""
Joins the checkpoint pieces device_run.py wrote (ckpt.part0, ckpt.part1, ...) and casts its float16 weights back to
float32, the dtype robomimic's policy_from_checkpoint builds the networks in.

    python results/image_rgbd/rebuild_checkpoint.py /work/.device/<files_at> runs/image_rgbd/model.pth
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import torch


def as_float(value):
    """float16 tensors (nested in dicts) as float32."""
    if isinstance(value, dict):
        return type(value)((k, as_float(v)) for k, v in value.items())
    if torch.is_tensor(value) and value.dtype == torch.float16:
        return value.float()
    return value


def main(folder: str, output: str) -> None:
    parts = sorted(Path(folder).glob("ckpt.part*"), key=lambda p: int(p.name.removeprefix("ckpt.part")))
    ckpt = torch.load(io.BytesIO(b"".join(p.read_bytes() for p in parts)), map_location="cpu", weights_only=False)
    ckpt["model"] = as_float(ckpt["model"])
    Path(output).parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, output)
    print(f"joined {len(parts)} pieces into {output}")


if __name__ == "__main__":
    main(*sys.argv[1:])
