"""Steps the recorded states of record_episode_states.py under whichever MuJoCo is imported: from each control step's
state and controls, one control period of physics substeps; prints the solver's time and iterations and how fast the
fastest grain ends. The same problems under two MuJoCo versions (PYTHONPATH=<folder of another mujoco>):

    python results/calibration/exploration/replay_solver_problems.py STATES.npz [SUBSTEPS]
    THREADS=2 ...: MuJoCo's own thread pool of that many workers (mju_threadpool, MuJoCo >= 3.10's API as of 3.17)
"""

import os
import sys
import time

import mujoco
import numpy as np

states = np.load(sys.argv[1])
substeps = int(sys.argv[2]) if len(sys.argv) > 2 else 12
model = mujoco.MjModel.from_xml_string(str(states["xml"]))
data = mujoco.MjData(model)
threads = int(os.environ.get("THREADS", "0"))
if threads:
    mujoco.mju_threadpool(data, threads)
grains = states["grains"]
iterations, fastest, seconds = [], [], 0.0
for qpos, qvel, ctrl in zip(states["qpos"], states["qvel"], states["ctrl"], strict=True):
    mujoco.mj_resetData(model, data)
    data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
    mujoco.mj_forward(model, data)
    start = time.perf_counter()
    for _ in range(substeps):
        mujoco.mj_step(model, data)
        iterations.append(int(data.solver_niter[0]))
    seconds += time.perf_counter() - start
    fastest.append(float(np.abs(data.cvel[grains, 3:]).max()))
it = np.array(iterations)
print(
    f"mujoco {mujoco.__version__}, {threads or 'no'} pool threads: "
    f"{len(states['qpos'])} control steps of {substeps} substeps in {seconds:.2f} s; "
    f"CG iterations mean {it.mean():.1f}, "
    f"at the cap ({model.opt.iterations}) {(it >= model.opt.iterations).mean():.2f}; "
    f"fastest grain after a step: median {np.median(fastest):.3f} m/s, max {max(fastest):.3f} m/s"
)
