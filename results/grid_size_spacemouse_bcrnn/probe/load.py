"""Where a policy loses its load: an episode on a grid bowl (seed 100000 + i) run by the evaluation's own loop
(veragmil_suite.environments.episode.run_until_done: success must hold 1 s), printing every 10 steps, and every
step a grain leaves the spoon after it was lifted clear, the stage the state shows, the grains in the spoon and
spilled, the spoon's tilt from level (degrees), its offset to the desired pose (mm) and the policy's translation
(OSC_POSE delta x, y, z); then how the episode ended. Run from the repository root:
    python results/grid_size_spacemouse_bcrnn/probe/load.py <checkpoint> <food> <bowl>..."""

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from veragmil_suite.environments.episode import run_until_done

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "grid_size_expert_bcq" / "probe"))
from bowl import grid_bowl  # noqa: E402


def traced(env, act: Callable, label: str) -> Callable:
    """``act`` that prints the episode's state before each action it is asked for (see the module's docstring)."""
    seen = {"t": 0, "spoon": 0, "lifted": False}

    def traced_act(obs: dict) -> np.ndarray:
        action = act(obs)
        info = env.scoop_info()
        seen["lifted"] |= info["stage"] in ("lifted clear", "at post-scoop pose")
        lost = seen["lifted"] and info["grains_in_spoon"] < seen["spoon"]
        if seen["t"] % 10 == 0 or lost:
            tilt = np.degrees(env._scoop_metrics()["spoon_tilt"])
            print(
                f"{label} step {seen['t']:3d} {info['stage']:18s} spoon {info['grains_in_spoon']:3d} "
                f"spilled {info['grains_spilled']:3d} tilt {tilt:5.1f} "
                f"to desired {np.round(1000 * obs['spoon_to_desired_pos'], 1)} "
                f"action {[round(float(a), 2) for a in action[:3]]}",
                flush=True,
            )
        seen["t"] += 1
        seen["spoon"] = info["grains_in_spoon"]
        return action

    return traced_act


checkpoint, food = sys.argv[1], sys.argv[2]
for episode in map(int, sys.argv[3:]):
    env, obs, act, step, _ = grid_bowl(checkpoint, food, episode)
    label = f"{food} bowl {episode}"
    end = run_until_done(traced(env, act, label), step, obs, env.control_freq, 400)
    print(f"{label}: {end.reason} after {end.steps} steps, stage {end.stage}", flush=True)
