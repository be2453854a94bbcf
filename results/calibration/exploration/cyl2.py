import dataclasses
import json
import sys
import time

from veragmil_suite.calibration.lifting_cylinder import lifting_cylinder
from veragmil_suite.models.foods import get_food

cfg = json.loads(sys.argv[1])
f = get_food(cfg["food"])
base = f.grain(cfg.get("base", "table1"))
g = dataclasses.replace(base, **{k: tuple(v) if isinstance(v, list) else v for k, v in cfg.get("grain", {}).items()})
if "mass_mg" in cfg:
    g = dataclasses.replace(g, density_kg_m3=cfg["mass_mg"] * 1e-6 / g.piece_volume_m3())
f = dataclasses.replace(f, calibrated=g)
t = time.time()
r = lifting_cylinder(
    f, "calibrated", seed=cfg.get("seed", 0), solver_options=cfg.get("solver"), scale=cfg.get("scale", 1.0)
)
out = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.as_dict().items()}
print(json.dumps({**cfg, **out, "wall": round(time.time() - t, 1)}), flush=True)
