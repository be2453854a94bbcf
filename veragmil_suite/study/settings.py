"""The study's settings: one object every stage reads (sizes, foods, profiles, algorithms, seeds, observation
sets, robot, workers, Ray), the algorithms' configs and the seeds' layout.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from veragmil_suite.devices.expert import get_profile
from veragmil_suite.evaluation.agents import parse_spec
from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.learning.observation_sets import (
    DEFAULT_OBSERVATION_SET,
    check_observation_set,
)
from veragmil_suite.models.foods import DEFAULT_PHYSICS, TRAINING_FOODS, UNSEEN_FOODS, check_physics, get_food
from veragmil_suite.models.humanoid import check_robot

# Seeds of recorded episodes and of evaluation episodes never meet: evaluation bowls are not training bowls.
EVAL_SEED_OFFSET = 100_000
# torch threads of a training run unless $VERAGMIL_TORCH_THREADS says otherwise (robomimic's train() sets 2)
ROBOMIMIC_TORCH_THREADS = 2
# Seeds of the foods' recordings are this far apart (by the food's place in the catalog, seen foods first), so
# every demo of a dataset has its own bowl and pile, whichever foods a run records.
FOOD_SEED_STRIDE = 1000


class StageError(RuntimeError):
    """A stage's child process failed; the message ends with the tail of its log."""


@dataclass
class PipelineSettings:
    """Sizes of one run: the small defaults finish in minutes on 2 cores; the paper's sizes are in docs/study.md.

    ``demos_per_food`` and ``eval_steps`` may list several values (learning curves): each demo count trains its
    own model on the first N demos of each food, and each model is evaluated at every step count of
    ``eval_steps`` (gradient steps, multiples of ``steps_per_epoch``; by default only at the end of training).
    ``algo_epochs`` (algorithm -> epochs) gives an algorithm its own budget instead of ``epochs``: BC-RNN costs 7x
    BC's time per gradient step. Each algorithm is evaluated at the end of its own training, and at the listed
    ``eval_steps`` its training reaches.
    ``agents`` (name -> agent SPEC of veragmil_suite.evaluation.agents) are evaluated beside the run's own, on the same
    bowls: a pretrained checkpoint, another operator profile, a recorded dataset.
    ``train_seeds`` (default: ``seed + 1`` alone) trains each model once per seed, on the same data: the spread
    between training seeds of one recipe is as large as the differences between recipes, so comparisons need it.
    ``obs_sets`` (veragmil_suite.learning.observation_sets) trains each model once per observation set, on the same
    data; every model's column names its set.
    """

    output_dir: str
    profiles: list[str] = field(default_factory=lambda: ["expert"])
    algos: list[str] = field(default_factory=lambda: ["bc"])
    train_foods: list[str] = field(default_factory=lambda: list(TRAINING_FOODS))
    eval_foods: list[str] = field(default_factory=lambda: list(TRAINING_FOODS + UNSEEN_FOODS))
    demos_per_food: list[int] = field(default_factory=lambda: [2])
    epochs: int = 20
    steps_per_epoch: int = 100
    eval_steps: list[int] | None = None
    algo_epochs: dict[str, int] = field(default_factory=dict)
    episodes: int = 3
    processes: int = 2
    seed: int = 0
    horizon: int = 400
    n_grains: int | None = None
    physics: str = DEFAULT_PHYSICS  # the grains every stage records and evaluates on (veragmil_suite.models.foods)
    robot: str = "XArm7"  # records, trains and evaluates with this robot (veragmil_suite.models.humanoid: the G1)
    score_demonstrators: bool = True
    train_seeds: list[int] | None = None
    obs_sets: list[str] = field(default_factory=lambda: [DEFAULT_OBSERVATION_SET])
    agents: dict[str, str] = field(default_factory=dict)
    ray: str | None = None  # None: local processes; else a Ray cluster's address (distributed.THIS_MACHINE: here)

    def __post_init__(self):
        for food in [*self.train_foods, *self.eval_foods]:
            get_food(food)  # a ValueError naming the accepted foods
        check_physics(self.physics)
        check_robot(self.robot)
        unknown = sorted(set(self.algos) - set(ALGORITHMS))
        if unknown:
            raise ValueError(f"unknown algorithm(s) {unknown}; accepted: {sorted(ALGORITHMS)}")
        for profile in self.profiles:
            get_profile(profile)
        if isinstance(self.demos_per_food, int):
            self.demos_per_food = [self.demos_per_food]
        self.demos_per_food = sorted(set(int(n) for n in self.demos_per_food))
        for name in ("epochs", "steps_per_epoch", "episodes", "processes", "horizon"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be a positive integer, got {getattr(self, name)!r}")
        if not self.demos_per_food or self.demos_per_food[0] < 1:
            raise ValueError(f"demos_per_food must be positive integers, got {self.demos_per_food!r}")
        unknown = sorted(set(self.algo_epochs) - set(ALGORITHMS))
        if unknown:
            raise ValueError(f"algo_epochs names unknown algorithm(s) {unknown}; accepted: {sorted(ALGORITHMS)}")
        for algo, epochs in self.algo_epochs.items():
            if int(epochs) < 1:
                raise ValueError(f"algo_epochs of {algo} must be a positive integer, got {epochs!r}")
        total = max(self.total_steps_of(algo) for algo in self.algos)
        steps = sorted(set(int(k) for k in (self.eval_steps or [])))
        bad = [k for k in steps if k < 1 or k > total or k % self.steps_per_epoch]
        if bad:
            raise ValueError(
                f"eval_steps {bad} are not checkpoints of this training: multiples of steps_per_epoch "
                f"({self.steps_per_epoch}) up to epochs x steps_per_epoch ({total})"
            )
        self.eval_steps = steps or None
        if isinstance(self.train_seeds, int):
            self.train_seeds = [self.train_seeds]
        self.train_seeds = list(dict.fromkeys(int(s) for s in self.train_seeds or [self.seed + 1]))
        if any(s < 0 for s in self.train_seeds):
            raise ValueError(f"train_seeds must be integers >= 0 (torch's seeds), got {self.train_seeds!r}")
        if isinstance(self.obs_sets, str):
            self.obs_sets = [self.obs_sets]
        self.obs_sets = list(dict.fromkeys(check_observation_set(name) for name in self.obs_sets))
        if not self.obs_sets:
            raise ValueError("obs_sets must name at least one observation set")
        own = set(self.own_agents())
        for name, spec in self.agents.items():
            parse_spec(spec)  # a ValueError naming the accepted forms
            if name in own:
                raise ValueError(
                    f"agent name {name!r} is taken by one of this run's own; name it otherwise (NAME=SPEC)"
                )

    def epochs_of(self, algo: str) -> int:
        return int(self.algo_epochs.get(algo, self.epochs))

    def total_steps_of(self, algo: str) -> int:
        return self.epochs_of(algo) * self.steps_per_epoch

    def steps_of(self, algo: str) -> list[int]:
        """The gradient steps at which ``algo``'s checkpoints are evaluated."""
        total = self.total_steps_of(algo)
        if self.eval_steps is None:
            return [total]
        own_end = {total} if algo in self.algo_epochs else set()
        return sorted({k for k in self.eval_steps if k <= total} | own_end)

    @property
    def sweeps_steps(self) -> bool:
        """Whether the run's checkpoints are evaluated at more than one step count."""
        return len({k for algo in self.algos for k in self.steps_of(algo)}) > 1

    def model_label(
        self,
        profile: str,
        algo: str,
        demos_per_food: int,
        steps: int,
        train_seed: int | None = None,
        obs_set: str = DEFAULT_OBSERVATION_SET,
    ) -> str:
        """A trained checkpoint's column: profile, algorithm and observation set, plus demos and steps when the run
        sweeps them (or its algorithms train for different budgets), plus the training seed when there are several
        (without ``train_seed``: the recipe's label, which names all its seeds)."""
        label = f"{profile} {ALGORITHMS[algo].label} {obs_set} obs"
        label += f" {demos_per_food} demos" if len(self.demos_per_food) > 1 else ""
        label += f" {_steps_label(steps)} steps" if self.sweeps_steps else ""
        label += f" seed {train_seed}" if train_seed is not None and len(self.train_seeds) > 1 else ""
        return label

    def run_name(
        self, profile: str, algo: str, demos_per_food: int, train_seed: int, obs_set: str = DEFAULT_OBSERVATION_SET
    ) -> str:
        """A training run's folder; the default seed's and observation set's have no suffix, so studies from before
        seeds and observation sets resume."""
        name = f"{profile}_{algo}_{demos_per_food}demos_{self.total_steps_of(algo)}steps"
        name += f"_obs-{obs_set}" if obs_set != DEFAULT_OBSERVATION_SET else ""
        return name if train_seed == self.seed + 1 else f"{name}_seed{train_seed}"

    def own_agents(self) -> list[str]:
        """The columns this run makes itself: each profile's operator (when scored) and each checkpoint."""
        names = [f"{p} operator" for p in self.profiles] if self.score_demonstrators else []
        for profile in self.profiles:
            names += [
                self.model_label(profile, algo, n, k, s, obs)
                for algo in self.algos
                for obs in self.obs_sets
                for n in self.demos_per_food
                for s in self.train_seeds
                for k in self.steps_of(algo)
            ]
        return names


def _steps_label(steps: int) -> str:
    return f"{steps // 1000}k" if steps % 1000 == 0 else str(steps)
