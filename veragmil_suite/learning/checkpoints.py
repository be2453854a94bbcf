"""robomimic checkpoints read as robomimic's ``FileUtils.load_dict_from_checkpoint`` reads them (``torch.load`` of
the file, onto the CPU), without importing robomimic: its import, torchvision's with it, costs seconds that a
program reading only a checkpoint's metadata or checking its keys need not pay."""

import os


def read_checkpoint(path: str) -> dict:
    """The checkpoint's dict (its algo_name, config, env_metadata, shape_metadata and model), tensors on the CPU."""
    import torch  # heavy: torch, only when a checkpoint is read

    return torch.load(os.path.expanduser(path), map_location="cpu")
