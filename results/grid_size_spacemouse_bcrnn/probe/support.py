"""Are the grid's start stalls starts the demonstrations do not cover? Resets ScoopGranular with the seed of every
recorded attempt (kept and discarded) and of every grid bowl (100000 + i), takes the spoon's start relative to the
bowl (eef minus bowl position, mm), and prints per grid bowl the distance to the nearest kept demo's start beside
the agents' successes and start stalls there (from episodes.csv files); then, over fresh reset seeds, how many
starts lie farther than 10, 20 and 30 mm from every kept demo for 30, 60 and all kept demos.
Run from the repository root:
    python results/grid_size_spacemouse_bcrnn/probe/support.py <recording folder> <episodes.csv>...
The recording folder holds the study's per-food files (data/<profile>/<food>.hdf5); each one's attempts log gives
its seeds. A kept demo's recorded first observation must equal its reset's (checked: the starts are the envs')."""

import csv
import json
import sys
from collections import defaultdict
from pathlib import Path

import h5py
import numpy as np
import robosuite

import veragmil_suite  # noqa: F401  (registers ScoopGranular)

GRID_BOWLS = 20
FRESH_SEEDS = range(500000, 500400)
RADII_MM = (10, 20, 30)

folder, csv_files = Path(sys.argv[1]), sys.argv[2:]
attempts, recorded = [], {}
env_kwargs = None
for path in sorted(folder.glob("*.hdf5")):
    with h5py.File(path, "r") as f:
        data = f["data"]
        env_kwargs = env_kwargs or json.loads(data.attrs["env_args"])["env_kwargs"]
        attempts += json.loads(data.attrs["attempts"])
        for name in data:
            obs = data[name]["obs"]
            seed = int(data[name].attrs["seed"])
            recorded[(path.stem, seed)] = 1000 * (obs["robot0_eef_pos"][0] - obs["bowl_pos"][0])

env_kwargs.update(has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False, food="rice")
env = robosuite.make("ScoopGranular", **env_kwargs)


def start(seed: int) -> np.ndarray:
    """The start of an attempt as the recording draws it: the env reseeded at its reset."""
    obs = env.reset(seed=seed)
    return 1000 * (obs["robot0_eef_pos"] - obs["bowl_pos"])


def grid_start(bowl: int) -> np.ndarray:
    """A grid bowl's start as veragmil-evaluate draws it: a fresh env made with the bowl's seed, then reset."""
    bowl_env = robosuite.make("ScoopGranular", **{**env_kwargs, "seed": 100000 + bowl})
    obs = bowl_env.reset()
    bowl_env.close()
    return 1000 * (obs["robot0_eef_pos"] - obs["bowl_pos"])


kept, dropped = [], []
worst = 0.0
for attempt in attempts:
    s = start(attempt["seed"])
    if attempt["kept"]:
        worst = max(worst, float(np.abs(s - recorded[(attempt["food"], attempt["seed"])]).max()))
        kept.append(s)
    else:
        dropped.append((s, attempt["food"], attempt["seed"], attempt["stage"], attempt["end_reason"]))
kept = np.array(kept)
print(f"{len(kept)} kept demos, {len(dropped)} discarded attempts in {folder}; a kept demo's reset start differs from")
print(f"its recorded first observation by at most {worst:.2g} mm")
span = ", ".join(f"{axis} {lo:.0f}..{hi:.0f}" for axis, lo, hi in zip("xyz", kept.min(axis=0), kept.max(axis=0)))
print(f"kept starts span {span} mm; spread (sd) {np.round(kept.std(axis=0), 1)} mm")


def nearest(points: np.ndarray, demos: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points[:, None, :] - demos[None, :, :], axis=2).min(axis=1)


print("\ndiscarded attempts (the operator failed): start, nearest kept demo start")
for s, food, seed, stage, reason in dropped:
    gap = nearest(s[None], kept)[0]
    print(f"  {food:9s} seed {seed:5d} {stage:18s} {reason:8s} start {np.round(s, 1)} nearest {gap:5.1f} mm")

# per grid bowl: successes and start stalls of each agent over the seven foods
success, stalls, agents = defaultdict(int), defaultdict(int), []
for name in csv_files:
    for row in csv.DictReader(open(name)):
        key = (row["agent"], int(row["episode"]))
        agents += [row["agent"]] if row["agent"] not in agents else []
        success[key] += row["success"] == "True"
        stalls[key] += row["stage"] == "start"

grid = np.array([grid_start(i) for i in range(GRID_BOWLS)])
near = nearest(grid, kept)
print("\ngrid bowls: start (mm from the bowl), nearest kept demo start (mm); per agent successes/7 (start stalls)")
for i, a in enumerate(agents):
    print(f"  agent {i}: {a}")
for b in np.argsort(-near):
    cells = " ".join(f"{success[(a, b)]}({stalls[(a, b)]})" for a in agents)
    print(f"  bowl {b:2d} start {np.round(grid[b], 0)} nearest {near[b]:5.1f}  {cells}")
for lo, hi in ((0, 15), (15, 25), (25, np.inf)):
    bowls = [b for b in range(GRID_BOWLS) if lo <= near[b] < hi]
    if bowls:
        rate = [round(100 * sum(success[(a, b)] for b in bowls) / (7 * len(bowls))) for a in agents]
        stall = [sum(stalls[(a, b)] for b in bowls) for a in agents]
        print(f"  nearest {lo}-{hi} mm: {len(bowls)} bowls, success {rate} %, start stalls {stall}")

fresh = np.array([start(s) for s in FRESH_SEEDS])
rng = np.random.default_rng(0)
seeds = f"seeds {FRESH_SEEDS.start}..{FRESH_SEEDS.stop - 1}"
print(f"\n{len(fresh)} fresh resets ({seeds}): % farther than {RADII_MM} mm from every kept start")
for n in (30, 60, len(kept)):
    shares = []
    for _ in range(20 if n < len(kept) else 1):
        d = nearest(fresh, kept[rng.choice(len(kept), n, replace=False)])
        shares.append([100 * np.mean(d > r) for r in RADII_MM])
    print(f"  {n:3d} demos: {np.round(np.mean(shares, axis=0), 1)}")
print(f"grid bowls farther than {RADII_MM} mm: {[int(np.sum(near > r)) for r in RADII_MM]} of {GRID_BOWLS}")
all_kept = nearest(fresh, kept)
far = int(np.argmax(near))
print(
    f"farthest fresh reset from the {len(kept)} kept starts: {all_kept.max():.1f} mm; "
    f"bowl {far} ({near[far]:.1f} mm) lies beyond {100 * np.mean(all_kept < near[far]):.2f}% of fresh resets"
)
