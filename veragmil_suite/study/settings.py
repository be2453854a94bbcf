"""The study's settings: one object every stage reads (sizes, foods, profiles, algorithms, seeds, observation
sets, robot, workers, Ray), the algorithms' configs and the seeds' layout.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import MISSING, dataclass, field
from typing import Any

from veragmil_suite.devices.expert import get_profile
from veragmil_suite.environments.arguments import check_grain_count
from veragmil_suite.evaluation.agents import SPEC_HELP, parse_agent_argument, parse_spec
from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.learning.observation_sets import (
    DEFAULT_OBSERVATION_SET,
    UNNAMED_RUNS_OBSERVATION_SET,
    check_observation_set,
)
from veragmil_suite.models.foods import DEFAULT_PHYSICS, TRAINING_FOODS, UNSEEN_FOODS, check_physics, get_food
from veragmil_suite.models.humanoid import check_robot
from veragmil_suite.utils import cli
from veragmil_suite.utils.numbers import first_repeated, is_whole, seed_span_problem

# Seeds of recorded episodes and of evaluation episodes never meet: evaluation bowls are not training bowls.
EVAL_SEED_OFFSET = 100_000
# torch threads of a training run unless $VERAGMIL_TORCH_THREADS says otherwise (robomimic's train() sets 2)
ROBOMIMIC_TORCH_THREADS = 2
# Seeds of the foods' recordings are this far apart (by the food's place in the catalog, seen foods first), so
# every demo of a dataset has its own bowl and pile, whichever foods a run records.
FOOD_SEED_STRIDE = 1000


class StageError(RuntimeError):
    """A stage's child process failed; the message ends with the tail of its log."""


@dataclass(frozen=True)
class Option:
    """How veragmil-study and veragmil-quickstart take a setting on their command line: their parser is built from
    these (scripts/study.py), so a new setting is one field here with its Option.

    ``flags`` defaults to ``--<the field's name, dashed>``; ``parse(given, default)`` turns what the option gave (None
    when it was not given) into the field's value, and makes the option's own default the settings' (shown in
    ``help`` as ``{default}``, through ``show``).
    """

    help: str
    kind: Callable[[str], Any] | None = None
    flags: tuple[str, ...] = ()
    aliases: tuple[str, ...] = ()
    action: str | None = None
    metavar: str | None = None
    parse: Callable[[Any, Any], Any] | None = None
    show: Callable[[Any], str] = str


def _algo_epochs(pairs: list[tuple[str, int]]) -> dict[str, int]:
    """--algo-epochs as a dict; an algorithm given twice is refused (which budget was meant?)."""
    twice = first_repeated([algo for algo, _ in pairs])
    if twice is not None:
        raise ValueError(f"algo_epochs gives {twice} two budgets: give one")
    return dict(pairs)


def setting(option: Option, default: Any = MISSING, factory: Callable[[], Any] | Any = MISSING) -> Any:
    """A PipelineSettings field with its command-line option."""
    return field(default=default, default_factory=factory, metadata={"option": option})


def agent_columns(texts: list[str] | None, defaults: dict[str, str]) -> dict[str, str]:
    """``--agent`` values as name -> SPEC (``defaults`` when none is given); ValueError for a bad or repeated one."""
    if texts is None:
        return dict(defaults)
    agents: dict[str, str] = {}
    for text in texts:
        name, spec = parse_agent_argument(text)
        if name in agents:
            raise ValueError(f"two agents are named {name!r}: give each a NAME= of its own")
        agents[name] = spec
    return agents


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

    output_dir: str = setting(
        Option(
            "where data, runs and tables go; an existing one is resumed (default: {default}/<date-time>)",
            cli.output_folder,
            parse=lambda given, default: given or os.path.join(default, time.strftime("%Y%m%d-%H%M%S")),
        )
    )
    profiles: list[str] = setting(Option("operator profiles", cli.ListOf(cli.profile)), factory=lambda: ["expert"])
    algos: list[str] = setting(Option("algorithms trained", cli.ListOf(cli.algo)), factory=lambda: ["bc"])
    train_foods: list[str] = setting(
        Option("foods recorded", cli.ListOf(cli.food)), factory=lambda: list(TRAINING_FOODS)
    )
    eval_foods: list[str] = setting(
        Option("foods evaluated", cli.ListOf(cli.food)), factory=lambda: list(TRAINING_FOODS + UNSEEN_FOODS)
    )
    demos_per_food: list[int] = setting(
        Option(
            "the paper: 30; several values train one model each (a learning curve over data)", cli.ListOf(cli.count)
        ),
        factory=lambda: [2],
    )
    epochs: int = setting(Option("the configs' own: 2000", cli.count), 20)
    steps_per_epoch: int = setting(Option("gradient steps per epoch", cli.count), 100)
    eval_steps: list[int] | None = setting(
        Option(
            "evaluate the checkpoints at these gradient steps (a learning curve; default: the last only)",
            cli.ListOf(cli.count),
        ),
        None,
    )
    algo_epochs: dict[str, int] = setting(
        Option(
            "this algorithm's own number of epochs instead of --epochs (repeat for more), e.g. bc_rnn=40: BC-RNN "
            "costs 7x BC's time per gradient step; it is evaluated at its end and at the --eval-steps it reaches",
            cli.KeyValue(cli.algo, cli.count, "ALGO=EPOCHS"),
            action="append",
            metavar="ALGO=EPOCHS",
            parse=lambda pairs, default: _algo_epochs(pairs) if pairs else dict(default),
        ),
        factory=dict,
    )
    episodes: int = setting(Option("evaluation episodes per food and model", cli.count), 3)
    processes: int = setting(
        Option(
            "parallel recording and evaluation processes (with --ray, the least number of pieces in flight)",
            cli.count,
        ),
        2,
    )
    seed: int = setting(Option("first recording seed", cli.seed), 0)
    horizon: int = setting(Option("longest episode, control steps", cli.count), 400)
    n_grains: int | None = setting(Option("grains in the bowl (default: each food's own)", cli.count), None)
    physics: str = setting(
        Option(
            "the grain models every stage records and evaluates on (veragmil_suite.models.foods.PHYSICS)",
            cli.physics,
        ),
        DEFAULT_PHYSICS,
    )
    robot: str = setting(
        Option(
            "the robot that records, and that the models and operators scoop with (G1FixedLowerBody: the G1, "
            "with the humanoid extra)",
            cli.robot,
            flags=("--robots",),
            aliases=("--robot",),
        ),
        "XArm7",
    )
    score_demonstrators: bool = setting(
        Option(
            "do not score the scripted operators themselves (the Human column), e.g. when measure_expert has",
            flags=("--no-operators",),
            action="store_false",
        ),
        True,
    )
    train_seeds: list[int] | None = setting(
        Option(
            "train each model once per seed (torch's), on the same data and scored on the same episodes; "
            "eval/seeds.md gives each recipe's mean and range over them (default: --seed + 1 alone)",
            cli.ListOf(cli.seed),
            metavar="SEED",
        ),
        None,
    )
    obs_sets: list[str] = setting(
        Option(
            "train each model once per low-dim observation set, named in its column (veragmil_suite.learning."
            "observation_sets): object holds grain counts, no-load what a real robot could observe, no-load-size "
            "(the configs') no-load and the food's piece size, no-load-rot no-load and the turn to the post-scoop "
            "orientation, wrench no-load and the wrist's force-torque sensor",
            cli.ListOf(cli.observation_set),
        ),
        factory=lambda: [DEFAULT_OBSERVATION_SET],
    )
    drop_noops: bool = setting(
        Option(
            "train on each profile's data without its no-op steps (veragmil-drop-noops: the operator's pauses, "
            "which policies learn as stalls), written beside it as data/<profile>-no-noops.hdf5; the models' "
            "columns and runs say no-noops",
            action="store_true",
        ),
        False,
    )
    rnn_horizon: int | None = setting(
        Option(
            "evaluate the recurrent models (BC-RNN, and any --agent's) with their hidden state reset every N rollout "
            "steps instead of their configs' algo.rnn.horizon (the training sequence length, 10); their columns "
            "say rnn.horizon N",
            cli.count,
        ),
        None,
    )
    agents: dict[str, str] = setting(
        Option(
            f"also evaluate this agent beside the run's own (repeat for more): SPEC is {SPEC_HELP} (default: "
            "{default})",
            cli.agent,
            flags=("--agent",),
            action="append",
            metavar="[NAME=]SPEC",
            parse=lambda texts, default: agent_columns(texts, default),
            show=lambda agents: ", ".join(f"{name}={spec}" for name, spec in agents.items()) or "none",
        ),
        factory=dict,
    )
    # None: local processes; else a Ray cluster's address (distributed.THIS_MACHINE: here). Its option is
    # distributed.add_ray_argument's, shared with the programs whose pieces run as Ray tasks.
    ray: str | None = None

    def __post_init__(self):
        for name in ("train_foods", "eval_foods", "profiles", "algos"):
            value = getattr(self, name)
            if isinstance(value, str) or not isinstance(value, (list, tuple)) or not value:
                raise ValueError(f"{name} must be a non-empty list of names, got {value!r}")
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
            if not (is_whole(getattr(self, name)) and getattr(self, name) >= 1):
                raise ValueError(f"{name} must be a positive integer, got {getattr(self, name)!r}")
        if not (is_whole(self.seed) and self.seed >= 0):
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        # the last seed the run derives from its first: its last evaluation episode's
        seeds_problem = seed_span_problem(self.seed, EVAL_SEED_OFFSET + self.episodes, "recording and evaluation")
        if seeds_problem:
            raise ValueError(seeds_problem)
        for food in dict.fromkeys([*self.train_foods, *self.eval_foods]):
            check_grain_count(self.n_grains, get_food(food), self.physics)
        if not self.demos_per_food or self.demos_per_food[0] < 1:
            raise ValueError(f"demos_per_food must be positive integers, got {self.demos_per_food!r}")
        unknown = sorted(set(self.algo_epochs) - set(ALGORITHMS))
        if unknown:
            raise ValueError(f"algo_epochs names unknown algorithm(s) {unknown}; accepted: {sorted(ALGORITHMS)}")
        untrained = sorted(set(self.algo_epochs) - set(self.algos))
        if untrained:
            raise ValueError(f"algo_epochs names {', '.join(untrained)}, which algos {self.algos} does not train")
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
        if self.rnn_horizon is not None:
            if int(self.rnn_horizon) < 1:
                raise ValueError(f"rnn_horizon must be a positive integer, got {self.rnn_horizon!r}")
            recurrent = sorted(name for name, algo in ALGORITHMS.items() if algo.recurrent)
            if not any(ALGORITHMS[algo].recurrent for algo in self.algos):
                raise ValueError(
                    f"rnn_horizon applies to recurrent algorithms ({', '.join(recurrent)}); algos {self.algos} has none"
                )
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
        label += " no-noops" if self.drop_noops else ""
        label += f" rnn.horizon {self.rnn_horizon}" if self.rnn_horizon and ALGORITHMS[algo].recurrent else ""
        label += f" {demos_per_food} demos" if len(self.demos_per_food) > 1 else ""
        label += f" {_steps_label(steps)} steps" if self.sweeps_steps else ""
        label += f" seed {train_seed}" if train_seed is not None and len(self.train_seeds) > 1 else ""
        return label

    def run_name(
        self, profile: str, algo: str, demos_per_food: int, train_seed: int, obs_set: str = DEFAULT_OBSERVATION_SET
    ) -> str:
        """A training run's folder; the default seed's and the ``object`` set's have no suffix, so studies from before
        seeds and observation sets resume."""
        name = f"{profile}_{algo}_{demos_per_food}demos_{self.total_steps_of(algo)}steps"
        name += f"_obs-{obs_set}" if obs_set != UNNAMED_RUNS_OBSERVATION_SET else ""
        name += "_no-noops" if self.drop_noops else ""
        return name if train_seed == self.seed + 1 else f"{name}_seed{train_seed}"

    def training_data(self, profile: str) -> str:
        """The file under data/ that ``profile``'s models train on: its merged recording, or with ``drop_noops``
        that recording without its no-op steps."""
        return f"{profile}-no-noops.hdf5" if self.drop_noops else f"{profile}.hdf5"

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
