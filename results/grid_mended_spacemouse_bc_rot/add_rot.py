"""Copies a merged dataset recorded before ``spoon_to_desired_rot`` existed and adds it to every demo's obs and
next_obs, computed from the stored ``robot0_eef_quat_site`` (the eef site's orientation, the sensor's input) by the
sensor's own function. Checks the first demo's first step against the sensor on its restored state. Run from the
repository root: python results/grid_mended_spacemouse_bc_rot/add_rot.py <in.hdf5> <out.hdf5>"""

import shutil
import sys

import h5py
import numpy as np
import robosuite.utils.transform_utils as T

from veragmil_suite.data.replay import DemoEnvs
from veragmil_suite.environments.start_pose import rotation_to_post_scoop

source, target = sys.argv[1], sys.argv[2]
shutil.copyfile(source, target)
with h5py.File(target, "r+") as f:
    for name in f["data"]:
        for group in ("obs", "next_obs"):
            g = f["data"][name][group]
            turns = np.array([rotation_to_post_scoop(T.quat2mat(q)) for q in g["robot0_eef_quat_site"][()]])
            g.create_dataset("spoon_to_desired_rot", data=turns)
    first = f["data"][sorted(f["data"], key=lambda n: int(n.split("_")[-1]))[0]]
    envs = DemoEnvs(f)
    _, obs = envs.start(first)
    sensed = obs["spoon_to_desired_rot"]
    stored = first["obs"]["spoon_to_desired_rot"][0]
    envs.close()
    print(f"{len(f['data'])} demos; first step: sensor {np.round(sensed, 6)}, added {np.round(stored, 6)}")
    assert np.allclose(sensed, stored, atol=1e-6), "the added observation differs from the sensor's"
