"""Does sampling the GMM get BC-RNN GMM off the start? The study's rice episodes (same seeds and bowls) rolled out by
its checkpoint as evaluated (the config's low_noise_eval: each mode's mean) and by a copy whose config samples the
mixture; beside them the lowest spoon point of the first demos. Run from the repository root after the study:

    python results/grid_calibrated_bcrnn_gmm/probe_start.py runs/grid_calibrated --episodes 10
"""

import argparse
import glob
import json
from pathlib import Path

import h5py
import torch

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.evaluation.agents import EpisodeTask, parse_spec, run_episode


def sampled_copy(path: str) -> str:
    """The checkpoint with algo.gmm.low_noise_eval off, beside it."""
    checkpoint = torch.load(path, map_location="cpu", weights_only=False)
    config = json.loads(checkpoint["config"])
    config["algo"]["gmm"]["low_noise_eval"] = False
    checkpoint["config"] = json.dumps(config, indent=4)
    out = str(Path(path).with_name("model_epoch_40_sampled.pth"))
    torch.save(checkpoint, out)
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("study")
    parser.add_argument("--episodes", type=int, default=10)
    args = parser.parse_args()
    study = Path(args.study)
    (path,) = glob.glob(str(study / "runs" / "expert_bc_rnn_gmm_*" / "*" / "models" / "model_epoch_40.pth"))
    with h5py.File(study / "data" / "expert.hdf5") as f:
        lows = [float(f["data"][d]["obs"]["robot0_eef_pos"][:, 2].min()) for d in list(f["data"])[:10]]
    print(json.dumps({"first 10 demos: lowest spoon z (m)": [round(z, 3) for z in lows]}))
    for mode, checkpoint in (("means", path), ("sampled", sampled_copy(path))):
        for episode in range(args.episodes):
            task = EpisodeTask(mode, parse_spec(checkpoint), "rice", episode, 100000 + episode, 400)
            task.env_kwargs["physics"] = "calibrated"
            record = run_episode(task)
            row = {"mode": mode, "episode": episode, "success": record.success, "stage": record.stage}
            print(json.dumps({**row, "steps": record.steps}), flush=True)


if __name__ == "__main__":
    main()
