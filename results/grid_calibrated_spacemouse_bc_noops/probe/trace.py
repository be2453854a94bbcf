"""Replays grid episodes of a checkpoint (same food, seed, horizon, physics as the evaluation) and prints, every 25
steps, the spoon against the rim's centre, its tilt, the policy's action and the episode's stage; the per-step trace
goes to trace_<episodes>.json beside this file.
Run from the repository root:
    python results/grid_calibrated_spacemouse_bc_noops/probe/trace.py <checkpoint> rice:3 rice:0
"""

import json
import sys
from pathlib import Path

import numpy as np

from veragmil_suite.evaluation.agents import EpisodeTask, _checkpoint_env, init_worker, parse_spec

init_worker()
traces = []
for food, episode in (arg.split(":") for arg in sys.argv[2:]):
    task = EpisodeTask(
        agent="probe",
        spec=parse_spec(sys.argv[1]),
        food=food,
        episode=int(episode),
        seed=100000 + int(episode),
        horizon=400,
        env_kwargs={"physics": "calibrated"},
    )
    env, obs, act, step = _checkpoint_env(task)
    rows = []
    for t in range(400):
        action = np.asarray(act(obs), dtype=float)
        obs, _, done, info = step(action)
        m = env._scoop_metrics()
        rows.append(
            dict(
                t=t,
                action=action[:6].round(3).tolist(),
                spoon_minus_rim=(m["spoon_pos"] - env._rim_center()).round(4).tolist(),
                tilt_deg=round(float(np.degrees(m["spoon_tilt"])), 1),
                stage=info.get("stage"),
            )
        )
        if done:
            break
    env.close()
    traces.append(dict(food=food, episode=int(episode), rows=rows))
    for r in rows[::25]:
        print(
            food,
            episode,
            r["t"],
            "spoon - rim",
            r["spoon_minus_rim"],
            "tilt",
            r["tilt_deg"],
            "action",
            r["action"],
            r["stage"],
            flush=True,
        )
name = "_".join(arg.replace(":", "") for arg in sys.argv[2:])
json.dump(traces, open(Path(__file__).parent / f"trace_{name}.json", "w"))
