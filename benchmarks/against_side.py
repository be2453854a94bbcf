"""One side of benchmarks/bench_against.py: whole expert episodes in the process of that side's checkout and MuJoCo.

Imports nothing at its top but the standard library: the base side's checkout may be older than any module of this
one, so only what both have is imported, in the function, from the side's own path.
"""

from __future__ import annotations

from pathlib import Path


def _first_module(*names: str):
    """The first of ``names`` that imports (a module's place in this checkout, then in older ones)."""
    import importlib  # in the child, from that side's checkout

    for name in names:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError:
            continue
    raise ModuleNotFoundError(f"none of {names} in this checkout")


def side_figures(
    food: str, episodes: int, lift_steps: int, sleep_off: bool, physics: str | None = None, n_grains: int | None = None
) -> dict:
    """One side's figures, in the process of that side's checkout and MuJoCo (only API both sides have)."""
    import time  # in the child, from that side's checkout

    import mujoco  # in the child, from that side's checkout
    import robosuite  # in the child, from that side's checkout

    import veragmil_suite  # in the child, from that side's checkout

    # each module where this checkout keeps it, or where a checkout from before the role folders (#35) did
    expert = _first_module("veragmil_suite.devices.expert", "veragmil_suite.expert")
    episode = _first_module("veragmil_suite.environments.episode", "veragmil_suite.episode")
    bench = _first_module("veragmil_suite.scripts.bench", "veragmil_suite.bench")
    ScriptedScooper, run_until_done = expert.ScriptedScooper, episode.run_until_done
    env_rate = getattr(bench, "env_rate", None) or bench._env_rate  # steps/s held still, after one step

    headless = dict(has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    lift = robosuite.make("Lift", robots="XArm7", **headless)
    lift_rate = env_rate(lift, lift_steps)
    lift.close()

    kwargs = dict(robots="XArm7", food=food, pile_variants=1, seed=0, **headless)
    if sleep_off:
        kwargs["sleep_tolerance"] = None
    if physics is not None:
        kwargs["physics"] = physics
    if n_grains is not None:
        kwargs["n_grains"] = n_grains
    env = robosuite.make("ScoopGranular", **kwargs)
    expert = ScriptedScooper(env, "expert")

    def agent(obs):
        return None if expert.done else expert.executed(expert.act(obs))

    steps, seconds, successes = 0, 0.0, 0
    for k, seed in enumerate([0, *range(episodes)]):  # the first, untimed, settles or loads the piles
        obs = env.reset()
        expert.reset(seed=seed)
        start = time.perf_counter()
        end = run_until_done(agent, env.step, obs, env.control_freq, env.horizon)
        if k:
            seconds += time.perf_counter() - start
            steps += end.steps
            successes += end.reason == "success"
    env.close()
    return dict(
        checkout=str(Path(veragmil_suite.__file__).resolve().parent.parent),
        mujoco=mujoco.__version__,
        lift_rate=lift_rate,
        rate=steps / seconds,
        steps=steps,
        successes=successes,
    )
