"""Each grid bowl (seed 100000 + i) as its episode starts: the spoon above the bowl, beside how many of the three
seeds' 7 foods never reached the pile there; and the same start height over the demos the policies learned from.
Run from the repository root: python results/grid_calibrated_spacemouse_bc_noops/probe/bowls.py <checkpoint>"""

import collections
import csv
import sys

import h5py
import numpy as np

from veragmil_suite.evaluation.agents import EpisodeTask, _checkpoint_env, init_worker, parse_spec

init_worker()
with open("results/grid_calibrated_spacemouse_bc_noops/episodes.csv") as f:
    starts = collections.Counter(int(r["episode"]) for r in csv.DictReader(f) if r["stage"] == "start")
for ep in range(20):
    task = EpisodeTask(
        agent="probe",
        spec=parse_spec(sys.argv[1]),
        food="rice",
        episode=ep,
        seed=100000 + ep,
        horizon=400,
        env_kwargs={"physics": "calibrated"},
    )
    env, obs, _, _ = _checkpoint_env(task)
    rim = env._scoop_metrics()["spoon_pos"] - env._rim_center()
    above = obs["robot0_eef_pos"] - obs["bowl_pos"]
    print(
        f"bowl {ep:2d}: never reached the pile in {starts[ep]:2d} of 21; spoon above the bowl (eef - bowl_pos) "
        f"{above[2] * 100:.1f} cm, above the rim's centre {rim[2] * 100:.1f} cm",
        flush=True,
    )
    env.close()
with h5py.File("runs/grid_sm_bc_noops_s1/data/spacemouse-no-noops.hdf5") as f:
    z = np.array([f[f"data/{d}/obs/robot0_eef_pos"][0, 2] - f[f"data/{d}/obs/bowl_pos"][0, 2] for d in f["data"]])
print(
    f"the {len(z)} demos' starts, eef - bowl_pos: {z.min() * 100:.1f}-{z.max() * 100:.1f} cm, median "
    f"{np.median(z) * 100:.1f}, {np.sum(z >= 0.063)} at or above 6.3 cm"
)
