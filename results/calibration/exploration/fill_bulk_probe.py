"""Bulk density of the lifting cylinder's poured fill alone (the benchmark's bulk column), without the lift or the
spoonful: python results/calibration/exploration/fill_bulk_probe.py FOOD TUBE_SCALE [SEED]"""
import math, sys, time, numpy as np, mujoco
import veragmil_suite  # noqa
from veragmil_suite.calibration import lifting_cylinder as lc
from veragmil_suite.calibration.scene import run_until_rest
from veragmil_suite.models.foods import FOODS
from veragmil_suite.models.grains import GrainPile
from veragmil_suite.models.dish import DishShape
food = FOODS[sys.argv[1]]; scale = float(sys.argv[2]); seed = int(sys.argv[3]) if len(sys.argv) > 3 else 0
t0 = time.time()
radius, _, n = lc.tube_size(food, "calibrated", scale)
pile = GrainPile(food, n, np.random.default_rng(seed), physics="calibrated")
shape = DishShape(rim_semi_axes=(radius, radius), floor_semi_axes=(radius, radius), depth=10.0, wall_half_thickness=lc.STAVE_HALF_THICKNESS_M, floor_half_thickness=0.01)
lattice = pile.lattice_qpos(shape, rim_center=np.array([0.0, 0.0, 10.0]))
th = float(lattice[:, 2].max() + pile.radii.max()) + 0.02
m = mujoco.MjModel.from_xml_string(lc._model_xml(pile, radius, th, "calibrated", None))
d = mujoco.MjData(m)
adr = np.array([m.joint(j).qposadr[0] for j in pile.joint_names])
d.qpos[adr[:, None] + np.arange(7)] = lattice
ids = np.array([m.body(b).id for b in pile.body_names])
rest, fast = run_until_rest(m, d, ids, 4.0 if scale < 1 else 8.0)
fill = lc._fill_height(d.xpos[ids], pile.thickness_radii, radius, 2 * float(pile.radii.mean()))
vol = math.pi * radius**2 * fill
mass = m.body_mass[ids].sum()
print(f"{sys.argv[1]} scale {scale} seed {seed}: {n} grains in a {radius*1000:.0f} mm tube, fill {fill*1000:.1f} mm, "
      f"bulk {mass/vol/1000:.3f} g/cm3, packing {pile.volumes_m3.sum()/vol:.2f}, grain {1e6*m.body_mass[ids].mean():.0f} mg, "
      f"at rest {rest}, escaped {fast}, sim {d.time:.1f} s, wall {time.time()-t0:.0f} s", flush=True)
pos = d.xpos[ids]
outside = int(((pos[:, 2] < 0) | (np.hypot(pos[:, 0], pos[:, 1]) > radius + 0.005)).sum())
print(f"  grains below the support or outside the tube: {outside} of {n}; stack top at the start {th:.2f} m")
