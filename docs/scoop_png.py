"""Renders docs/scoop.png, the README's picture: the scripted expert lifting a spoonful of rice (seed 3).

MUJOCO_GL=osmesa python docs/scoop_png.py
"""

import os

os.environ.setdefault("MUJOCO_GL", "osmesa")

import mujoco  # noqa: E402
import robosuite  # noqa: E402
from PIL import Image  # noqa: E402

import veragmil_suite  # noqa: E402, F401
from veragmil_suite.devices.expert import ScriptedScooper  # noqa: E402

env = robosuite.make("ScoopGranular", robots="XArm7", food="rice", has_renderer=False, has_offscreen_renderer=True)
obs = env.reset(seed=3)
expert = ScriptedScooper(env, "expert", seed=3)
while not (expert.phase == "lift" and expert.phase_steps >= 8):
    obs, _, _, _ = env.step(expert.agent(obs))
camera = mujoco.MjvCamera()
camera.type = mujoco.mjtCamera.mjCAMERA_FREE
camera.lookat[:] = env._rim_center() + [0, 0, 0.03]
camera.distance, camera.azimuth, camera.elevation = 0.42, 150, -28
renderer = mujoco.Renderer(env.sim.model._model, height=400, width=640)
renderer.update_scene(env.sim.data._data, camera=camera)
Image.fromarray(renderer.render()).save(os.path.join(os.path.dirname(os.path.abspath(__file__)), "scoop.png"))
