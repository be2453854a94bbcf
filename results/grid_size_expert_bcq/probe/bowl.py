"""A grid bowl (env seed 100000 + i, the grid's evaluation seeds, calibrated physics) with a checkpoint's policy, as
veragmil-evaluate runs it; the probes of this folder step it themselves."""

import veragmil_suite.evaluation.agents as agents


def grid_bowl(checkpoint: str, food: str, bowl: int) -> tuple:
    """The environment, first observation, act(obs) and step of the bowl, and the checkpoint's RolloutPolicy."""
    task = agents.EpisodeTask(
        agent="probe",
        spec=agents.parse_spec(checkpoint),
        food=food,
        episode=bowl,
        seed=100000 + bowl,
        horizon=400,
        env_kwargs={"physics": "calibrated"},
    )
    env, obs, act, step = agents.episode_env(task)
    rollout, _ = agents._policy(task.spec.target, "cpu", None)
    return env, obs, act, step, rollout
