"""
Console entry points that run robomimic's own scripts (train, run_trained_agent, get_dataset_info,
playback_dataset, dataset_states_to_obs) on our environment, with their own command lines.

Each one installs the compatibility layer (veragmil_suite.robomimic_compat), which also registers ScoopGranular,
then runs the script's ``if __name__ == "__main__":`` block in the script's own module. A failed run exits
non-zero (robomimic's train.py catches its errors and would exit 0) and nothing ever waits on a prompt.

    veragmil-train --config configs/json/bc.json --dataset demos/scoop.hdf5
    python -m veragmil_suite.scripts.robomimic_entry train --config ...   (same, without the console script)
"""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import sys
from collections.abc import Callable
from pathlib import Path

from veragmil_suite import robomimic_compat

SCRIPTS = {
    "train": "robomimic.scripts.train",
    "run-agent": "robomimic.scripts.run_trained_agent",
    "dataset-info": "robomimic.scripts.get_dataset_info",
    "playback": "robomimic.scripts.playback_dataset",
    "states-to-obs": "robomimic.scripts.dataset_states_to_obs",
}
# per script: its console name, and the options whose value must be an existing file
FILE_OPTIONS = {
    "robomimic.scripts.train": ("veragmil-train", ("--config", "--dataset")),
    "robomimic.scripts.run_trained_agent": ("veragmil-run-agent", ("--agent",)),
    "robomimic.scripts.get_dataset_info": ("veragmil-robomimic-dataset-info", ("--dataset",)),
    "robomimic.scripts.playback_dataset": ("veragmil-robomimic-playback", ("--dataset",)),
    "robomimic.scripts.dataset_states_to_obs": ("veragmil-robomimic-states-to-obs", ("--dataset",)),
}


def _main_block(module) -> object:
    """The compiled body of a script's ``if __name__ == "__main__":`` block (its argparse and its call)."""
    path = inspect.getsourcefile(module)
    with open(path) as f:
        tree = ast.parse(f.read(), filename=path)
    for node in tree.body:
        test = node.test if isinstance(node, ast.If) else None
        if (
            isinstance(test, ast.Compare)
            and isinstance(test.left, ast.Name)
            and test.left.id == "__name__"
            and isinstance(test.comparators[0], ast.Constant)
            and test.comparators[0].value == "__main__"
        ):
            return compile(ast.Module(body=node.body, type_ignores=[]), path, "exec")
    raise RuntimeError(f"{path} has no __main__ block to run")


def _bad_file_arguments(program: str, argv: list[str], options: tuple[str, ...]) -> str | None:
    """One line naming the first of ``options`` in ``argv`` whose file is missing or unreadable, else None: caught
    before robomimic's script would fail on it with a traceback."""
    for i, arg in enumerate(argv[:-1]):
        if arg not in options:
            continue
        path = Path(argv[i + 1])
        if path.is_dir():
            return f"{program}: {arg} {path}: is a directory, not a file"
        if not path.is_file():
            return f"{program}: {arg} {path}: no such file"
        if path.suffix == ".json":
            try:
                json.loads(path.read_text())
            except (ValueError, UnicodeDecodeError) as e:
                return f"{program}: {arg} {path}: not JSON ({e})"
    return None


def run_script(module_name: str, argv: list[str] | None = None, prepare: Callable | None = None) -> int:
    """
    Runs one robomimic script as its command line would, and returns the process exit code.

    Args:
        module_name: e.g. "robomimic.scripts.train"
        argv: the script's arguments (default: this process's)
        prepare: called with the imported script module before it runs; returns an object whose ``failed``
            tells whether a run that returned normally failed anyway
    """
    args = sys.argv[1:] if argv is None else list(argv)
    program, options = FILE_OPTIONS.get(module_name, ("veragmil", ()))
    problem = _bad_file_arguments(program, args, options)
    if problem is not None:
        print(problem, file=sys.stderr)
        return 2
    robomimic_compat.install()
    module = importlib.import_module(module_name)
    outcome = prepare(module) if prepare is not None else None
    code = _main_block(module)
    saved_argv = sys.argv
    sys.argv = [module.__file__, *args]
    try:
        with robomimic_compat.no_prompts():
            exec(code, module.__dict__)
    except SystemExit as stop:  # argparse: --help, bad arguments
        return stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    finally:
        sys.argv = saved_argv
    if outcome is not None and outcome.failed:
        print(f"veragmil: training failed: {outcome.error!r}", file=sys.__stderr__)
        return 1
    return 0


def train_main(argv: list[str] | None = None) -> int:
    """veragmil-train: robomimic's train.py (--config, --algo, --name, --dataset, --debug)."""
    return run_script(SCRIPTS["train"], argv, prepare=robomimic_compat.prepare_train_script)


def run_agent_main(argv: list[str] | None = None) -> int:
    """veragmil-run-agent: robomimic's run_trained_agent.py (--agent, --n_rollouts, --video_path, ...)."""
    return run_script(SCRIPTS["run-agent"], argv)


def get_dataset_info_main(argv: list[str] | None = None) -> int:
    """veragmil-robomimic-dataset-info: robomimic's get_dataset_info.py (--dataset, --filter_key, --verbose)."""
    return run_script(SCRIPTS["dataset-info"], argv)


def playback_dataset_main(argv: list[str] | None = None) -> int:
    """veragmil-robomimic-playback: robomimic's playback_dataset.py (--dataset, --video_path, --use-actions, ...)."""
    return run_script(SCRIPTS["playback"], argv)


def dataset_states_to_obs_main(argv: list[str] | None = None) -> int:
    """veragmil-robomimic-states-to-obs: robomimic's dataset_states_to_obs.py (--dataset, --output_name, ...)."""
    return run_script(SCRIPTS["states-to-obs"], argv, prepare=robomimic_compat.prepare_states_to_obs_script)


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
    if not argv or argv[0] not in _COMMANDS:
        print(f"usage: python -m {__spec__.name if __spec__ else __name__} {{{','.join(_COMMANDS)}}} [arguments]")
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    return _COMMANDS[argv[0]](argv[1:])


if __name__ == "__main__":
    sys.exit(main())
