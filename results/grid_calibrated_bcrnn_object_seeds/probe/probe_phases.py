"""How each phase of the scripted expert's recorded demos ended: its waypoint reached, or its time limit (a switch
no observation shows). Replays each demo's seed with the expert (or another scripted profile, ``--profile``) and
logs every phase change."""

import argparse
import json
import sys

import h5py
import robosuite

import veragmil_suite  # noqa: F401
from veragmil_suite.data.collection import run_episode
from veragmil_suite.data.recording import EpisodeRecorder
from veragmil_suite.devices.expert import PHASES
from veragmil_suite.devices.operators import ScriptedOperator


class Logged(ScriptedOperator):
    def begin(self, seed=None):
        super().begin(seed)
        self.log = []

    def action(self, obs):
        e = self.expert
        before, steps = e.phase_index, e.phase_steps
        out = super().action(obs)
        if e.phase_index != before:
            ph = PHASES[before]
            timed = steps * e.dt >= ph.max_time_s * e.profile.phase_time_scale
            self.log.append((ph.name, steps, "time" if timed else "reached"))
        return out


def main():
    p = argparse.ArgumentParser()
    p.add_argument("data_dir")
    p.add_argument("--foods", nargs="+", default=["rice", "buckwheat", "barley", "pasta"])
    p.add_argument("--demos", type=int, default=10)
    p.add_argument("--profile", default="expert")
    a = p.parse_args()
    for food in a.foods:
        with h5py.File(f"{a.data_dir}/{food}.hdf5", "r") as f:
            kwargs = json.loads(f["data"].attrs["env_args"])["env_kwargs"]
            names = sorted(f["data"].keys(), key=lambda s: int(s.split("_")[1]))[: a.demos]
            seeds = [int(f["data"][n].attrs["seed"]) for n in names]
            lens = [int(f["data"][n].attrs["num_samples"]) for n in names]
        env = robosuite.make("ScoopGranular", **kwargs)
        op = Logged(env, a.profile, seeds[0])
        for seed, n in zip(seeds, lens):
            reason = run_episode(env, EpisodeRecorder(env), op, 1.0, False, False, seed=seed)
            print(json.dumps({"food": food, "seed": seed, "recorded_steps": n, "reason": reason, "phases": op.log}))
            sys.stdout.flush()
        env.close()


if __name__ == "__main__":
    main()
