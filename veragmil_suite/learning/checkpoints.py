"""robomimic checkpoints read as robomimic's ``FileUtils.load_dict_from_checkpoint`` reads them (``torch.load`` of
the file, onto the CPU), without importing robomimic: its import, torchvision's with it, costs seconds that a
program reading only a checkpoint's metadata or checking its keys need not pay."""

import json
import os
import zipfile


def read_checkpoint(path: str, weights: bool = True) -> dict:
    """The checkpoint's dict (its algo_name, config, env_metadata, shape_metadata and model), tensors on the CPU.

    ``weights=False``, for a reader of its metadata only: the model's tensors are mapped from the file, not read (a
    Diffusion Policy checkpoint holds 527 MB of them: 0.4 s to read from the page cache and 2 s from disk, against
    0.02-0.04 s to map). A file of torch's legacy format, which cannot be mapped, is read whole."""
    import torch  # heavy: torch, only when a checkpoint is read

    path = os.path.expanduser(path)
    return torch.load(path, map_location="cpu", mmap=not weights and zipfile.is_zipfile(path))


def config_rnn_horizon(config: dict) -> int | None:
    """How many rollout steps the recurrent policy of a robomimic config keeps its hidden state before robomimic
    resets it (``algo.rnn.horizon``); None for a policy without an RNN."""
    rnn = config.get("algo", {}).get("rnn", {})
    return int(rnn["horizon"]) if rnn.get("enabled") else None


def rnn_horizon_of(ckpt: dict) -> int | None:
    """config_rnn_horizon of a checkpoint's config (stored as JSON text)."""
    return config_rnn_horizon(json.loads(ckpt["config"]))


def with_rnn_horizon(ckpt: dict, horizon: int) -> dict:
    """The checkpoint with its recurrent policy's hidden state reset every ``horizon`` rollout steps: the config's
    ``algo.rnn.horizon``, which robomimic reads when it builds the rollout policy (training used
    ``train.seq_length`` and is unchanged). ValueError for a policy without an RNN."""
    config = json.loads(ckpt["config"])
    if config_rnn_horizon(config) is None:
        raise ValueError(f"a {ckpt.get('algo_name', 'policy')} checkpoint without an RNN has no rnn horizon to set")
    config["algo"]["rnn"]["horizon"] = int(horizon)
    return {**ckpt, "config": json.dumps(config, indent=4)}
