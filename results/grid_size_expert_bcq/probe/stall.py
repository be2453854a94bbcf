"""Where a BCQ policy loses a scoop: the action sampler's (VAE's) proposals, the actor's perturbed candidates (where
the config has an actor) and the critic's choice among them, every 10 steps of an episode on a grid bowl (seed
100000 + i). The spoon rises out of the pile on +z: each line gives the grains in the spoon, the end effector's height
over the bowl's origin, the z of the chosen action, the candidates' mean and highest z, the VAE's proposals' mean z,
the correlation between the candidates' Q and their z, and the chosen 6-D action (OSC_POSE delta: x, y, z, then the
rotation's axis-angle). The torch generator is set back after each look, so the rollout is the evaluation's.
Run from the repository root: python results/grid_size_expert_bcq/probe/stall.py <checkpoint> <food> <bowl>..."""

import sys

import numpy as np
import torch
from bowl import grid_bowl

checkpoint, food = sys.argv[1], sys.argv[2]
EVERY = 10  # steps between looks
for episode in map(int, sys.argv[3:]):
    env, obs, act, step, rollout = grid_bowl(checkpoint, food, episode)
    algo = rollout.policy
    stages = []
    for t in range(400):
        if t % EVERY == 0:
            rng = torch.get_rng_state()
            with torch.no_grad():
                ob = rollout._prepare_observation(obs)
                n = algo.algo_config.critic.num_action_samples_rollout
                tiled = {k: v.repeat_interleave(n, dim=0) for k, v in ob.items()}
                proposals = algo.nets["action_sampler"](tiled, None)
                actor = algo.nets["actor"] if "actor" in algo.nets else None  # the configs' BCQ perturbs none
                candidates = actor(tiled, proposals, None) if actor is not None else proposals
                q = algo.nets["critic"][0](tiled, candidates, None).squeeze(-1)
            torch.set_rng_state(rng)
            z = candidates[:, 2].numpy()
            corr = float(np.corrcoef(q.numpy(), z)[0, 1]) if z.std() > 0 else float("nan")
            best = candidates[int(q.argmax())].numpy()
            chosen = best[2]
            print(
                f"bowl {episode} step {t:3d} {env.scoop_stage():18s} spoon {env.scoop_info()['grains_in_spoon']:3d} "
                f"eef z {1000 * (obs['robot0_eef_pos'][2] - obs['bowl_pos'][2]):+5.1f} mm "
                f"z chosen {chosen:+.2f} candidates mean {z.mean():+.2f} max {z.max():+.2f} "
                f"VAE mean {proposals[:, 2].mean():+.2f}  corr(Q, z) {corr:+.2f}  "
                f"action {[round(float(a), 2) for a in best]}",
                flush=True,
            )
        obs, _, done, info = step(act(obs))
        stages.append(env.scoop_stage())
        if done or env.scoop_info()["success"]:
            break
    print(f"bowl {episode}: success {env.scoop_info()['success']} steps {t + 1} last stage {stages[-1]}", flush=True)
