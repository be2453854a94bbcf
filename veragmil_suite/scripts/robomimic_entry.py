"""
Console entry points that run robomimic's own scripts (train, run_trained_agent, get_dataset_info,
playback_dataset, dataset_states_to_obs) on our environment, with their own command lines.

Each one installs the compatibility layer (veragmil_suite.learning.robomimic_compat), which also registers
ScoopGranular, parses its command line with the script's own parser (robomimic's option names; dashed spellings accepted
too), each option given a kind of value (veragmil_suite.utils.cli) so that a bad value, a missing or foreign file is
one line and exit 2 before anything runs, then runs the script's ``if __name__ == "__main__":`` block in the script's
own module on those arguments. A failed run exits non-zero (robomimic's train.py catches its errors and would exit 0)
and nothing ever waits on a prompt.

    veragmil-train --config configs/json/bc.json --dataset demos/scoop.hdf5
    python -m veragmil_suite.scripts.robomimic_entry train --config ...   (same, without the console script)
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import h5py

from veragmil_suite.data.schema import filter_key_demos, missing_observations
from veragmil_suite.learning import robomimic_compat, robomimic_scripts, training_resume
from veragmil_suite.learning.config_values import build_config
from veragmil_suite.learning.observation_sets import WRENCH_OBSERVATIONS
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError
from veragmil_suite.utils.rendering import has_display
from veragmil_suite.utils.whole_files import same_file

SCRIPTS = {
    "train": "robomimic.scripts.train",
    "run-agent": "robomimic.scripts.run_trained_agent",
    "dataset-info": "robomimic.scripts.get_dataset_info",
    "playback": "robomimic.scripts.playback_dataset",
    "states-to-obs": "robomimic.scripts.dataset_states_to_obs",
}


@dataclass(frozen=True)
class Script:
    """A robomimic script as a console program: its name here, and the kind (veragmil_suite.utils.cli) of each of
    its options that takes a value, by robomimic's name for it."""

    module: str
    prog: str
    kinds: dict[str, cli.Kind] = field(default_factory=dict)


_CAMERAS = cli.ListOf(cli.camera)
PROGRAMS = {
    "robomimic.scripts.train": Script(
        "robomimic.scripts.train",
        "veragmil-train",
        {
            "--config": cli.robomimic_config,
            "--algo": cli.robomimic_algo,
            "--name": cli.experiment_name,
            "--dataset": cli.robomimic_dataset,
        },
    ),
    "robomimic.scripts.run_trained_agent": Script(
        "robomimic.scripts.run_trained_agent",
        "veragmil-run-agent",
        {
            "--agent": cli.checkpoint,
            "--n_rollouts": cli.count,
            "--horizon": cli.count,
            "--env": cli.environment,
            "--video_path": cli.output_video,
            "--video_skip": cli.count,
            "--camera_names": _CAMERAS,
            "--dataset_path": cli.output_dataset,
            "--seed": cli.seed,
        },
    ),
    "robomimic.scripts.get_dataset_info": Script(
        "robomimic.scripts.get_dataset_info",
        "veragmil-robomimic-dataset-info",
        {"--dataset": cli.robomimic_dataset, "--filter_key": cli.text},
    ),
    "robomimic.scripts.playback_dataset": Script(
        "robomimic.scripts.playback_dataset",
        "veragmil-robomimic-playback",
        {
            "--dataset": cli.robomimic_dataset,
            "--filter_key": cli.text,
            "--n": cli.count,
            "--video_path": cli.output_video,
            "--video_skip": cli.count,
            # cameras, or with --use-obs the dataset's image observations (check_args tells which)
            "--render_image_names": cli.ListOf(cli.text),
        },
    ),
    "robomimic.scripts.dataset_states_to_obs": Script(
        "robomimic.scripts.dataset_states_to_obs",
        "veragmil-robomimic-states-to-obs",
        {
            "--dataset": cli.robomimic_dataset,
            "--output_name": cli.file_name,
            "--n": cli.count,
            "--camera_names": _CAMERAS,
            "--camera_height": cli.count,
            "--camera_width": cli.count,
            "--done_mode": cli.Integer(0, 2, accepted="0, 1 or 2 (robomimic's done modes)"),
        },
    ),
}


# the options naming a file a script writes (robomimic writes over it; ours refuse that unless --force)
OUTPUTS = {
    "robomimic.scripts.run_trained_agent": ("video_path", "dataset_path"),
    "robomimic.scripts.playback_dataset": ("video_path",),
    "robomimic.scripts.dataset_states_to_obs": ("output_name",),
}


def build_parser(module_name: str) -> cli.Parser:
    """robomimic's own parser of the script, with each option given its kind (PROGRAMS), adopted by our convention:
    robomimic's names, shown with dashes (--n-rollouts), robomimic's spelling (--n_rollouts) accepted as well."""
    script = PROGRAMS[module_name]
    robomimic_compat.install()  # robomimic's scripts import mujoco_py, which the compatibility layer stands in for
    parser = cli.script_parser(importlib.import_module(module_name))
    kinds = {action: next((script.kinds[s] for s in action.option_strings if s in script.kinds), None)
             for action in parser._actions}  # fmt: skip
    cli.adopt(parser, script.prog)
    for action in parser._actions:
        kind = kinds[action]
        if kind is None:
            continue
        action.type = kind
        if isinstance(kind, cli.ListOf):
            action.__class__ = cli.Flatten
    if module_name == SCRIPTS["train"]:
        parser.add_argument(
            "--resume",
            action="store_true",
            help="go on with the newest run of this experiment that was stopped (same config), from the state it "
            "saved last (every $VERAGMIL_RESUME_EVERY_S seconds, default 120); a new run when there is none",
        )
    if module_name in OUTPUTS:
        written = ", ".join(_option(dest) for dest in OUTPUTS[module_name])
        parser.add_argument("--force", action="store_true", help=f"overwrite {written} when it exists")
    return parser


def check_args(module_name: str, args: argparse.Namespace) -> None:
    """What robomimic's scripts assert or fail on later, refused before they run: UsageError names the conflict."""
    if module_name != "robomimic.scripts.train" and getattr(args, "dataset", "") is None:
        raise UsageError("give --dataset FILE (a robomimic dataset)")
    if getattr(args, "render", False):
        if getattr(args, "video_path", None) is not None:
            raise UsageError("give --render (on screen) or --video_path (a video), not both")
        if not has_display():
            raise UsageError("--render needs a display (no DISPLAY is set); write a video with --video_path instead")
        names = getattr(args, "camera_names", None) or getattr(args, "render_image_names", None) or []
        if len(names) > 1:
            raise UsageError("--render shows one camera; give one with --camera_names / --render_image_names")
    if module_name == "robomimic.scripts.train":
        if args.config is None and args.algo is None:
            raise UsageError("give --config FILE (a robomimic config) or --algo NAME (its default config)")
        if args.config is not None and args.algo is not None:
            raise UsageError("give --config or --algo, not both (the config names its algorithm)")
        config = training_config(args)
        if args.dataset is None:
            if config.train.data is None:
                raise UsageError("give --dataset FILE (a robomimic dataset), or name it in the config's train.data")
            cli.check_option("--config's train.data", config.train.data, cli.robomimic_dataset)
        default = f"robomimic's default {args.algo} config"
        whose = "--config's" if args.config is not None else f"{default}'s"
        cli.check_option(f"{whose} train.output_dir", config.train.output_dir, cli.output_folder)
        if args.name is None:
            cli.check_option(f"{whose} experiment.name", config.experiment.name, cli.experiment_name)
        check_observations_recorded(config, args.dataset or config.train.data, args.config or default)
    if module_name == "robomimic.scripts.playback_dataset" and args.use_obs:
        if args.video_path is None:
            raise UsageError("--use-obs plays the stored observations back into a video: give --video_path")
        if args.use_actions:
            raise UsageError("--use-obs plays stored observations, --use-actions replays actions: give one")
        args.render_image_names = _stored_images(args.dataset, args.render_image_names)
    elif module_name == "robomimic.scripts.playback_dataset":
        for name in args.render_image_names or []:
            cli.check_option("--render-image-names", name, cli.camera)
    if module_name == "robomimic.scripts.dataset_states_to_obs":
        cli.check_option("--output_name", _output_path(args, "output_name"), cli.output_dataset)
    if getattr(args, "filter_key", None) is not None:
        with h5py.File(args.dataset, "r") as f:
            filter_key_demos(f, args.filter_key)  # DatasetError names the keys the file has
    check_outputs(module_name, args)


def _stored_images(dataset: str, names: list[str] | None) -> list[str]:
    """The image observations --use-obs plays: ``names``, each one the dataset stores, or its first image."""
    with h5py.File(dataset, "r") as f:
        demos = list(f["data"])
        obs = f["data"][demos[0]].get("obs", {}) if demos else {}
        stored = [key for key in obs if key.endswith("_image")]
    if not stored:
        raise UsageError(f"{dataset} stores no image observations to play: render them with veragmil-render-obs")
    for name in names or []:
        if name not in stored:
            raise UsageError(
                f"--render-image-names {name}: with --use-obs, an image observation the dataset stores; accepted: "
                f"{', '.join(stored)}"
            )
    return names or stored[:1]


def training_config(args: argparse.Namespace) -> Any:
    """The robomimic config a training runs: its algorithm's defaults, updated by --config (already checked)."""
    return build_config(cli.json_file(args.config) if args.config is not None else {"algo_name": args.algo})


def _option(dest: str) -> str:
    """An option as the help shows it (--video-path for robomimic's --video_path)."""
    return "--" + dest.replace("_", "-")


def _output_path(args: argparse.Namespace, dest: str) -> str | None:
    """The file an output option names: states-to-obs's --output_name lies beside its --dataset."""
    value = getattr(args, dest, None)
    if dest == "output_name" and value is not None:
        return os.path.join(os.path.dirname(args.dataset), value)
    return value


def check_outputs(module_name: str, args: argparse.Namespace) -> None:
    """Refuses an output that is one of the script's inputs (robomimic would empty it before reading it), and one
    that exists unless --force."""
    inputs = [path for path in (getattr(args, "dataset", None), getattr(args, "agent", None)) if path is not None]
    for dest in OUTPUTS.get(module_name, ()):
        path = _output_path(args, dest)
        if path is None:
            continue
        if any(same_file(path, source) for source in inputs):
            raise UsageError(f"{_option(dest)} {path} is also an input: write it to a new file")
        cli.refuse_existing(path, args.force)


def check_observations_recorded(config: Any, dataset: str, source: str) -> None:
    """Refuses a training config (``source`` names it) whose observations ``dataset`` does not hold: robomimic would
    fail on the first one it reads, with a KeyError and its traceback."""
    keys = [key for names in config.observation.modalities.obs.values() for key in (names or [])]
    missing = missing_observations(dataset, keys) if keys else []
    if not missing:
        return
    if set(missing) <= set(WRENCH_OBSERVATIONS):
        hint = "record them with the wrist sensor (veragmil-collect --wrench; veragmil-study does for the wrench set)"
    elif any(key.endswith("_gripper_qpos") for key in missing):
        hint = (
            "the spoon has no gripper joints: train with configs/json/ (robomimic's templates with this task's "
            "observations) or leave the key out"
        )
    else:
        hint = "record them, or train on observations it holds"
    raise UsageError(f"{dataset} holds no {', '.join(missing)} observations, which {source} trains on; {hint}")


def _command(module_name: str, prepare: Callable | None = None) -> Callable[[list[str] | None], int]:
    """The console program of a robomimic script: our parse (kinds, spellings, checks), ``prepare(module, args)``
    of the script's module, then the script's own main block on the parsed arguments, under cli.command's
    handler."""

    @cli.command(lambda: build_parser(module_name))
    def main(args: argparse.Namespace) -> int:
        check_args(module_name, args)
        module = importlib.import_module(module_name)
        outcome = prepare(module, args) if prepare is not None else None
        code = cli.main_block(module)
        saved = sys.argv, sys.stdout, sys.stderr
        sys.argv = [module.__file__]
        try:
            with robomimic_scripts.no_prompts(), cli.parse_args_answering(lambda parser: args):
                exec(code, module.__dict__)
        except training_resume.ResumeRefused as refused:
            raise UsageError(str(refused)) from None
        finally:
            # robomimic's train script points stdout and stderr at its log for good: a caller's streams come back
            sys.argv, sys.stdout, sys.stderr = saved
        if outcome is not None and outcome.failed:
            print(f"veragmil: training failed: {outcome.error!r}", file=sys.__stderr__)
            return 1
        return 0

    return main


train_main = _command(
    SCRIPTS["train"], prepare=lambda module, args: robomimic_scripts.prepare_train_script(module, resume=args.resume)
)
train_main.__doc__ = "veragmil-train: robomimic's train.py (--config, --algo, --name, --dataset, --debug, --resume)."
run_agent_main = _command(
    SCRIPTS["run-agent"],
    prepare=lambda module, args: robomimic_scripts.prepare_outputs_whole(
        module, "run_trained_agent", ("dataset_path",)
    ),
)
run_agent_main.__doc__ = "veragmil-run-agent: robomimic's run_trained_agent.py (--agent, --n_rollouts, ...)."
get_dataset_info_main = _command(SCRIPTS["dataset-info"])
get_dataset_info_main.__doc__ = "veragmil-robomimic-dataset-info: robomimic's get_dataset_info.py (--dataset, ...)."
playback_dataset_main = _command(
    SCRIPTS["playback"],
    prepare=lambda module, args: robomimic_scripts.prepare_outputs_whole(module, "playback_dataset"),
)
playback_dataset_main.__doc__ = "veragmil-robomimic-playback: robomimic's playback_dataset.py (--dataset, ...)."
dataset_states_to_obs_main = _command(
    SCRIPTS["states-to-obs"], prepare=lambda module, args: robomimic_scripts.prepare_states_to_obs_script(module)
)
dataset_states_to_obs_main.__doc__ = "veragmil-robomimic-states-to-obs: robomimic's dataset_states_to_obs.py."


_COMMANDS = {
    "train": train_main,
    "run-agent": run_agent_main,
    "dataset-info": get_dataset_info_main,
    "playback": playback_dataset_main,
    "states-to-obs": dataset_states_to_obs_main,
}


def main(argv: list[str] | None = None) -> int:
    """``python -m veragmil_suite.scripts.robomimic_entry <command> [robomimic arguments]``."""
    argv = sys.argv[1:] if argv is None else argv
    prog = f"python -m {__spec__.name if __spec__ else __name__}"
    if argv and argv[0] in ("-h", "--help"):
        print(f"usage: {prog} {{{','.join(_COMMANDS)}}} [arguments]")
        return 0
    if not argv or argv[0] not in _COMMANDS:
        given = f"unknown command {argv[0]!r}" if argv else "give a command"
        print(f"{prog}: {given}; accepted: {', '.join(_COMMANDS)}", file=sys.stderr)
        return 2
    return _COMMANDS[argv[0]](argv[1:])


if __name__ == "__main__":
    sys.exit(main())
