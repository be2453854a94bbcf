"""Scores a checkpoint on the grid's bowls (seed 100000 + i) with each episode started as a recording started it
before 9f84426: right after env.reset(), the env restarted from its own model and state (a deterministic reset,
which loads the arm's controllers at the noise-free start pose, then the state set back) with the controllers left
aiming at that noise-free pose, so the first step pulls the spoon toward it. A plain evaluation's controllers aim at
the pose the initial joint noise gave. Everything else is veragmil_suite.evaluation.agents.run_episode. Writes one
JSON line per episode to <out.jsonl> (resumed).
Run from the repository root:
python results/start_mismatch/restarted_start.py <checkpoint> <agent name> <out.jsonl> [--plain] [--foods f ...]"""

import argparse
import dataclasses
import json
import multiprocessing
from pathlib import Path

import veragmil_suite.evaluation.agents as agents
from veragmil_suite.learning import robomimic_obs

FOODS = ("rice", "buckwheat", "barley", "pasta", "peas", "beans", "flakes")
plain_checkpoint_env = agents._checkpoint_env


def restart_as_before(env) -> None:
    """The recorder's restart as it was before 9f84426: the model reloaded by a deterministic reset, the state set
    back, and no ScoopGranular.hold_restored_pose: the controllers keep the noise-free pose."""
    state = env.sim.get_state().flatten()
    env.reset_from_xml_string(env.edit_model_xml(robomimic_obs.model_xml(env)))
    env.sim.reset()
    env.sim.set_state_from_flattened(state)
    env.sim.forward()
    env._restored_start = False


def restarted_checkpoint_env(task):
    env, _, act, step = plain_checkpoint_env(task)
    restart_as_before(env)
    return env, step.__self__.get_observation(), act, step


def score(args):
    (checkpoint, agent, food, episode, plain) = args
    agents._checkpoint_env = plain_checkpoint_env if plain else restarted_checkpoint_env
    task = agents.EpisodeTask(
        agent=agent,
        spec=agents.parse_spec(checkpoint),
        food=food,
        episode=episode,
        seed=100000 + episode,
        horizon=400,
        env_kwargs={"physics": "calibrated"},
    )
    return dataclasses.asdict(agents.run_episode(task))


if __name__ == "__main__":
    p = argparse.ArgumentParser()
    p.add_argument("checkpoint")
    p.add_argument("agent")
    p.add_argument("out", type=Path)
    p.add_argument("--plain", action="store_true", help="start as a plain evaluation does (a check)")
    p.add_argument("--foods", nargs="+", default=FOODS)
    p.add_argument("--episodes", nargs="+", type=int, default=list(range(20)))
    a = p.parse_args()
    done = set()
    if a.out.exists():
        done = {(r["food"], r["episode"]) for r in map(json.loads, a.out.read_text().splitlines())}
    todo = [(a.checkpoint, a.agent, f, e, a.plain) for f in a.foods for e in a.episodes if (f, e) not in done]
    with multiprocessing.Pool(2, initializer=agents.init_worker) as pool, open(a.out, "a") as out:
        for record in pool.imap_unordered(score, todo):
            out.write(json.dumps(record) + "\n")
            out.flush()
