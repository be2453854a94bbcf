import dataclasses
import json
import sys

from veragmil_suite.models.foods import get_food
from veragmil_suite.scripts.measure_expert import run_expert_episode

cfg = json.loads(sys.argv[1])
f = get_food(cfg["food"])
base = f.grain(cfg.get("base", "table1"))
g = dataclasses.replace(base, **{k: tuple(v) if isinstance(v, list) else v for k, v in cfg.get("grain", {}).items()})
if "mass_mg" in cfg:
    import numpy as np

    from veragmil_suite.models.grains import GrainPile

    f0 = dataclasses.replace(f, calibrated=g)
    m = GrainPile(f0, 100, np.random.default_rng(0), physics="calibrated").mass_properties()["mass"].mean() * 1e6
    g = dataclasses.replace(g, density_kg_m3=float(g.density_kg_m3 * cfg["mass_mg"] / m))
f = dataclasses.replace(f, calibrated=g)
kw = {"physics": "calibrated" if cfg.get("grain") or cfg.get("solver") else cfg.get("physics", "table1"), "food": f}
if cfg.get("solver"):
    kw["physics_solver_options"] = {k: str(v) for k, v in cfg["solver"].items()}
for seed in cfg.get("seeds", [0]):
    for _ in range(2 if seed == cfg.get("seeds", [0])[0] else 1):
        r = run_expert_episode(cfg["food"], seed, env_kwargs=kw)
    print(
        json.dumps(
            {
                **cfg,
                "seed": seed,
                **{
                    k: r[k]
                    for k in [
                        "end_reason",
                        "physics_error",
                        "success",
                        "grains_in_spoon",
                        "grains_spilled",
                        "spoon_mass_g",
                        "spilled_mass_g",
                        "steps",
                        "completion_time_s",
                        "wall_s",
                        "stage",
                    ]
                },
                "rate": round(r["steps"] / r["wall_s"], 2),
                "density": g.density_kg_m3,
            }
        ),
        flush=True,
    )
