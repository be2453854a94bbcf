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


def cast_floats(value, dtype: torch.dtype):
    """Floating-point tensors (nested in dicts) cast to ``dtype``; everything else as it is."""
    if isinstance(value, dict):
        return type(value)((k, cast_floats(v, dtype)) for k, v in value.items())
    if torch.is_tensor(value) and value.is_floating_point():
        return value.to(dtype)
    return value


def main(folder: str, output: str) -> None:
    parts = sorted(Path(folder).glob("ckpt.part*"), key=lambda p: int(p.name.removeprefix("ckpt.part")))
    ckpt = torch.load(io.BytesIO(b"".join(p.read_bytes() for p in parts)), map_location="cpu", weights_only=False)
    ckpt["model"] = cast_floats(ckpt["model"], torch.float32)
    Path(output).parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, output)
    print(f"joined {len(parts)} pieces into {output}")


if __name__ == "__main__":
    main(*sys.argv[1:])
