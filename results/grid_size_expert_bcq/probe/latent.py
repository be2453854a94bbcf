"""How much a BCQ checkpoint's action sampler (a conditional VAE) draws on its latent: at steps 0, 40 and 60 of a grid
bowl (seed 100000 + i), 100 decodes each with the latent at 0, drawn from the prior N(0, 1) and from N(0, 9); each
gives the z action's mean and spread and the spread over all 6 action dimensions. A decoder that ignores its latent
gives one action whatever is drawn, and the critic has nothing to choose among.
Run from the repository root: python results/grid_size_expert_bcq/probe/latent.py <checkpoint> <food> <bowl>"""

import sys

import torch
from bowl import grid_bowl

checkpoint, food, episode = sys.argv[1], sys.argv[2], int(sys.argv[3])
env, obs, act, step, rollout = grid_bowl(checkpoint, food, episode)
sampler = rollout.policy.nets["action_sampler"]
n = 100
for t in range(61):
    if t in (0, 40, 60):
        rng = torch.get_rng_state()
        with torch.no_grad():
            ob = rollout._prepare_observation(obs)
            tiled = {k: v.repeat_interleave(n, dim=0) for k, v in ob.items()}
            looks = []
            for name, scale in (("z = 0", 0.0), ("z ~ N(0, 1)", 1.0), ("z ~ N(0, 9)", 3.0)):
                actions = sampler.decode(
                    obs_dict=tiled, goal_dict=None, z=scale * torch.randn(n, sampler._vae.latent_dim)
                )
                a = actions["action"]
                looks.append(
                    f"{name}: z action {a[:, 2].mean():+.3f} sd {a[:, 2].std():.4f}, all dims sd {a.std(0).mean():.4f}"
                )
        torch.set_rng_state(rng)
        print(f"bowl {episode} step {t:2d} ({env.scoop_stage()}): " + "; ".join(looks), flush=True)
    obs, _, done, info = step(act(obs))
