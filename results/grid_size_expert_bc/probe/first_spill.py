"""Per grid bowl (seed 100000 + i) of an agent (a checkpoint, or "expert"): success, the step, stage and pieces in the
spoon at the first piece spilled, the step and load at which the post-scoop pose is first reached, the end, and the
eef's x from the rim's centre when it rises out of the pile (as lift_x.py measures it in a recording).
Run from the repository root: python results/grid_size_expert_bc/probe/first_spill.py <agent> <food> <bowl>..."""

import sys

import numpy as np

import veragmil_suite.evaluation.agents as agents

agent, food = sys.argv[1], sys.argv[2]
for episode in map(int, sys.argv[3:]):
    task = agents.EpisodeTask(
        agent="probe",
        spec=agents.parse_spec(agent),
        food=food,
        episode=episode,
        seed=100000 + episode,
        horizon=400,
        env_kwargs={"physics": "calibrated"},
    )
    env, obs, act, step = agents.episode_env(task)
    first = None
    reached = None
    rel = []
    for t in range(400):
        obs, _, done, info = step(act(obs))
        i = env.scoop_info()
        o = env._get_observations()
        rel.append(np.asarray(o["robot0_eef_pos"]) - np.asarray(o["bowl_pos"]))
        if first is None and i["grains_spilled"] > 0:
            first = (t + 1, env.scoop_stage(), i["grains_in_spoon"])
        if reached is None and env.scoop_stage() == "at post-scoop pose":
            reached = (t + 1, i["grains_in_spoon"], i["grains_spilled"])
        if done or i["success"]:
            break
    rel = np.array(rel)
    deepest = int(np.argmin(rel[:, 2]))
    lift_x = 1000 * rel[deepest + int(np.argmax(rel[deepest:, 2] > -0.005)), 0]
    print(
        f"bowl {episode}: success {i['success']} steps {t + 1} first spill {first} reached pose {reached} "
        f"final spoon {i['grains_in_spoon']} spilled {i['grains_spilled']} x at the lift {lift_x:.1f} mm",
        flush=True,
    )
