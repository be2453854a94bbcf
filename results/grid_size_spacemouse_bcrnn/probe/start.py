"""Where a policy holds still at the start: every 5 steps of an episode on a grid bowl (seed 100000 + i), the stage,
the end effector's position relative to the bowl's origin (mm), the spoon's offset to the desired pose (mm) and the
policy's 6-D action (OSC_POSE delta: x, y, z, then the rotation's axis-angle), up to step 100; then the episode's end.
Run from the repository root:
    python results/grid_size_spacemouse_bcrnn/probe/start.py <checkpoint> <food> <bowl>..."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "grid_size_expert_bcq" / "probe"))
from bowl import grid_bowl  # noqa: E402

checkpoint, food = sys.argv[1], sys.argv[2]
for episode in map(int, sys.argv[3:]):
    env, obs, act, step, _ = grid_bowl(checkpoint, food, episode)
    print(f"bowl {episode}: bowl at {np.round(1000 * obs['bowl_pos'], 1)} mm", flush=True)
    for t in range(400):
        action = act(obs)
        if t % 5 == 0 and t <= 100:
            rel = 1000 * (obs["robot0_eef_pos"] - obs["bowl_pos"])
            print(
                f"bowl {episode} step {t:3d} {env.scoop_stage():18s} eef-bowl {np.round(rel, 1)} "
                f"to desired {np.round(1000 * obs['spoon_to_desired_pos'], 1)} "
                f"action {[round(float(a), 2) for a in action]}",
                flush=True,
            )
        obs, _, done, _ = step(action)
        if done or env.scoop_info()["success"]:
            break
    print(f"bowl {episode}: success {env.scoop_info()['success']} steps {t + 1} stage {env.scoop_stage()}", flush=True)
