"""
Collect ScoopGranular demonstrations straight into a robomimic HDF5 file.

A superset of robosuite's robosuite/scripts/collect_human_demonstrations.py: its options (--environment, --robots,
--config, --arm, --camera, --controller, --device, --pos-sensitivity, --rot-sensitivity, --renderer, --max_fr,
--reverse_xy, --goal_update_mode, --directory) mean what they mean there, and its devices (keyboard, spacemouse,
dualsense, mjgui: robosuite's own device classes) are chosen with --device as there; ours add ``vr`` (a WebXR
headset, veragmil_suite.devices.VRDevice) and ``scripted`` (the scripted expert, veragmil_suite.devices.expert: no
human, no display, no prompt). Run it as ``veragmil-collect``, as ``python -m
veragmil_suite.scripts.collect_human_demonstrations`` or by its path, as robosuite's is run: the same program each way.

After each episode its metrics (success, spilled pieces and volume, completion time) are printed and stored, and
the operator keeps or discards it; discarded attempts are still logged, so a human operator's success rate counts
every attempt (the paper's "Human" column).

Each kept episode is flushed to the file when it ends: stopping the script (Ctrl-C, or killing it) loses at most
the episode in progress. Giving an existing file appends to it; --directory DIR records into a new
DIR/<time>/demo.hdf5, as robosuite's script does.

Attempt k (from 0) resets the environment with seed ``--seed`` + k (and seeds the scripted expert with it), so an
episode depends on its seed alone. The scripted device can record in ``--processes`` processes, or as Ray tasks with
``--ray [ADDRESS]`` (on the piles settled here): attempts run in parallel and are kept or discarded in seed order,
so the file is the same for any number of processes, wherever they run.

Example:
    veragmil-collect --device scripted --food rice --episodes 2 --output out.hdf5
    veragmil-collect --device keyboard --food pasta --episodes 30 --output pasta_keyboard.hdf5 --operator alice
    python collect_human_demonstrations.py --environment ScoopGranular --robots XArm7 --device spacemouse --directory d
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import sys
import time

import robosuite
from robosuite.controllers import ALL_COMPOSITE_CONTROLLERS, load_composite_controller_config

from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.data.collection import (
    KEEP_POLICIES,
    CollectionOutcome,
    FrameCap,
    collect,
    local_attempts,
    open_writer,
    parallel_attempts,
    recording_env_kwargs,
)
from veragmil_suite.data.recording import EpisodeRecorder
from veragmil_suite.devices.expert import PROFILES
from veragmil_suite.devices.operators import TeleopOperator, make_operator
from veragmil_suite.environments.episode import SUCCESS_HOLD_S
from veragmil_suite.models.humanoid import SPOON_ARM
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError, command
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.distributed import add_ray_argument, check_ray_argument
from veragmil_suite.utils.numbers import seed_span_problem
from veragmil_suite.utils.rendering import has_display, use_headless_rendering

# robosuite's devices (its collect_human_demonstrations.py), then ours
ROBOSUITE_DEVICES = ("keyboard", "spacemouse", "dualsense", "mjgui")
DEVICES = (*ROBOSUITE_DEVICES, "vr", "scripted")
# robosuite's env_configuration values mean something for two-robot tasks only; this task has one robot
ENV_CONFIGURATIONS = ("default",)


def build_parser() -> Parser:
    """robosuite's collect_human_demonstrations.py options, with their meaning there, and ours."""
    p = Parser(
        "veragmil-collect",
        description=__doc__.split("\n\n")[0].strip() + " Devices: " + ", ".join(DEVICES) + ".",
    )
    add = p.add_argument
    # robosuite's collect_human_demonstrations.py options, meaning what they mean there
    add(
        "--directory",
        type=cli.output_folder,
        default=None,
        help="as robosuite's: record into DIRECTORY/<time>/demo.hdf5 (a new folder per run); or give --output",
    )
    add("--environment", type=cli.environment, default="ScoopGranular", help="the robosuite environment")
    add(
        "--robots",
        aliases=["--robot"],
        type=cli.robot,
        default="XArm7",
        help="robosuite robot with the spoon: a single arm, or the Unitree G1 (G1FixedLowerBody, G1ArmsOnly; "
        "needs robosuite-models, the package's humanoid extra)",
    )
    add(
        "--config",
        type=cli.Choice("environment configuration", ENV_CONFIGURATIONS),
        default="default",
        help="robosuite's env_configuration (two-robot tasks only; this task has one robot)",
    )
    add(
        "--arm",
        type=cli.Choice("arm", ("right", "left")),
        default=SPOON_ARM,
        help=f"the arm the device drives: the spoon's ({SPOON_ARM})",
    )
    add(
        "--camera",
        type=cli.ListOf(cli.camera),
        nargs="*",
        default=None,
        help="the live window's camera(s) (several need --renderer mujoco; default: the first of --camera-names)",
    )
    add(
        "--controller",
        type=cli.controller,
        default="OSC_POSE",
        help="OSC_POSE (the task's gains), a robosuite composite controller (BASIC, ...) or a composite-controller "
        "JSON file, whose arm is OSC_POSE: every device and the expert send OSC_POSE deltas (mjgui: absolute poses)",
    )
    add("--device", type=cli.Choice("device", DEVICES), default="keyboard", help="who drives the spoon")
    add("--pos-sensitivity", type=cli.positive, default=1.0, help="teleoperation translation scale")
    add("--rot-sensitivity", type=cli.positive, default=1.0, help="teleoperation rotation scale")
    add(
        "--renderer",
        type=cli.Choice("renderer", ("mjviewer", "mujoco")),
        default="mjviewer",
        help="live window: MuJoCo's interactive viewer (mjviewer) or robosuite's OpenCV one (mujoco)",
    )
    add(
        "--max-fr",
        type=cli.frame_rate,
        default=None,
        help="at most this many control steps per second (robosuite's frame-rate cap; default: real time for "
        "people, as fast as it runs for the scripted expert)",
    )
    add("--reverse-xy", type=cli.boolean, default=False, help="dualsense: swap the joystick's x and y")
    add(
        "--goal-update-mode",
        type=cli.Choice("goal update mode", ("target", "achieved")),
        default="target",
        help="teleoperation devices: deltas from the last target or from the pose reached",
    )

    # ours
    add("--output", type=cli.output_dataset, default=None, help="HDF5 file (appended to when it exists)")
    add("--food", type=cli.food, default="rice")
    add("--episodes", type=cli.count, default=1, help="demonstrations to save")
    add("--control-freq", type=cli.control_freq, default=20, help="control rate, Hz (the paper's VR runs at 60)")
    add("--horizon", type=cli.count, default=400, help="longest episode, control steps")
    add("--n-grains", type=cli.count, default=None, help="grains in the bowl (default: the food's own)")
    add(
        "--physics",
        type=cli.physics,
        default=None,
        help="the grain models (veragmil_suite.models.foods.PHYSICS; default: the task's); recorded by name",
    )
    add(
        "--camera-names",
        aliases=["--cameras"],
        type=cli.ListOf(cli.camera),
        nargs="*",
        default=["overhead"],
        help="cameras recorded as <name>_image; none: low-dim only",
    )
    cli.add_image_size(p, 84, 84, old=["--camera-size"])
    add("--depth", action="store_true", help="also record <camera>_depth (metres)")
    add(
        "--wrench",
        action="store_true",
        help="also record the wrist force-torque sensor (robot0_eef_force, robot0_eef_torque: the wrench "
        "observation set's data)",
    )
    add(
        "--seed",
        type=cli.seed,
        default=None,
        help="attempt k runs with seed SEED + k (env and scripted expert); default 0, or when appending, the seed "
        "after the file's last",
    )
    add(
        "--processes",
        aliases=["--workers"],
        type=cli.count,
        default=1,
        help="scripted device: parallel recording processes (same file for any N)",
    )
    add(
        "--keep",
        type=cli.Choice("keep policy", KEEP_POLICIES),
        default=None,
        help="which episodes to save: ask the operator, all, or the successful ones "
        "(default: success for scripted, ask otherwise)",
    )
    add(
        "--max-attempts",
        type=cli.count,
        default=None,
        help="stop after this many episodes (default: 3x --episodes + 2 for scripted, unlimited otherwise)",
    )
    add(
        "--success-hold",
        type=cli.non_negative,
        default=SUCCESS_HOLD_S,
        help="end an episode once success held this long, s (0: success does not end it)",
    )
    add("--operator", type=cli.text, default=None, help="who demonstrates (stored with every demo)")
    add("--profile", type=cli.Choice("operator profile", sorted(PROFILES)), default="expert", help="scripted profile")
    add("--valid-ratio", type=cli.fraction_below_one, default=0.1, help="fraction of demos in mask/valid")
    add(
        "--render",
        type=cli.Choice("render mode", ("auto", "on", "off")),
        nargs="?",
        const="on",
        default="auto",
        help="live window: on (alone: --render, as robomimic's), off, or auto (for people with a display)",
    )
    add("--vr-host", type=cli.host, default="127.0.0.1", help="VR server address (0.0.0.0 for a Wi-Fi headset)")
    add("--vr-port", type=cli.port, default=8765, help="VR server port (0: any free one)")
    add(
        "--vr-allow-emulated",
        action="store_true",
        help="vr: drive with poses the headset only estimates (WebXR emulatedPosition: a controller out of the "
        "cameras' view, or a desktop emulator such as iwer, which marks every pose so); off: they release the grip",
    )
    add("--quiet", action="store_true", help="print only the per-episode lines and the summary")
    add_ray_argument(p, "the scripted attempts")
    return p


def check_args(args: argparse.Namespace) -> None:
    """What no single option's kind can tell: how they combine. UsageError names the conflict."""
    if (args.output is None) == (args.directory is None):
        raise UsageError("give --output FILE (appended to when it exists) or --directory DIR (robosuite's), one")
    if args.arm != SPOON_ARM:
        raise UsageError(f"--arm {args.arm}: the spoon is on the {SPOON_ARM} arm, which the device drives")
    if args.processes > 1 and args.device != "scripted":
        raise UsageError(f"--processes {args.processes} needs --device scripted (one person drives one device)")
    if args.ray is not None and args.device != "scripted":
        raise UsageError("--ray needs --device scripted (one person drives one device)")
    if args.device == "mjgui" and args.renderer != "mjviewer":
        raise UsageError("--device mjgui drags the spoon's target in MuJoCo's viewer: it needs --renderer mjviewer")
    if args.device in ("keyboard", "mjgui") and not has_display():
        raise UsageError(f"--device {args.device} needs a display (no DISPLAY is set)")
    if args.render == "on" and not has_display():
        raise UsageError("--render on needs a display (no DISPLAY is set): use --render off")
    if args.depth and not args.camera_names:
        raise UsageError("--depth records <camera>_depth beside each camera's image: give --camera-names")
    if args.keep == "ask" and args.device == "scripted":
        raise UsageError("--keep ask asks the person at the device; --device scripted keeps all or success")
    if args.max_attempts is not None and args.max_attempts < args.episodes:
        raise UsageError(
            f"--max-attempts {args.max_attempts} is fewer than --episodes {args.episodes}: every episode is an attempt"
        )
    if args.camera and len(args.camera) > 1 and args.renderer != "mujoco":
        raise UsageError("several --camera views need --renderer mujoco (robosuite's mjviewer shows one)")
    if args.device == "vr":
        cli.check_port_free(args.vr_host, args.vr_port)
    check_ray_argument(args)


def output_path(args: argparse.Namespace) -> str:
    """--output, or robosuite's --directory layout: DIRECTORY/<seconds>_<fraction>/demo.hdf5."""
    if args.output is not None:
        return args.output
    seconds, fraction = str(time.time()).split(".")
    return os.path.join(args.directory, f"{seconds}_{fraction}", "demo.hdf5")


def env_kwargs_from_args(args: argparse.Namespace) -> dict:
    """robosuite.make keyword arguments (besides the env name) for the command line, JSON-serializable."""
    return recording_env_kwargs(
        args.robots,
        args.food,
        controller_config(args.controller, args.robots, absolute=args.device == "mjgui"),
        control_freq=args.control_freq,
        horizon=args.horizon,
        n_grains=args.n_grains,
        physics=args.physics,
        cameras=args.camera_names or (),
        image_size=(args.camera_height, args.camera_width),
        depth=args.depth,
        wrench=args.wrench,
    )


def controller_config(value: str, robot: str, absolute: bool = False) -> dict:
    """
    The composite controller config for ``--controller`` (cli.controller checked its form): our OSC_POSE, robosuite's
    composite controller of that name, or a JSON file. ``absolute``: the arm takes absolute world-frame poses (what
    robosuite's mjgui device sends) instead of deltas. UsageError when the arm is not OSC_POSE.
    """
    if value == "OSC_POSE":
        config = load_scoop_controller_config("OSC_POSE", robot=robot)
    elif value in ALL_COMPOSITE_CONTROLLERS:
        config = copy.deepcopy(load_composite_controller_config(controller=value, robot=robot))
    else:
        with open(value) as f:
            config = json.load(f)
    arm = config.get("body_parts", {}).get("right", {})
    if arm.get("type") != "OSC_POSE":
        raise UsageError(
            f"--controller {value}: drives {robot}'s arm with {arm.get('type')!r}; collection needs OSC_POSE"
        )
    if absolute:
        arm.update(input_type="absolute", input_ref_frame="world")
    return config


@command(build_parser)
def main(args: argparse.Namespace) -> int:
    """veragmil-collect: record demonstrations (see --help)."""
    check_args(args)
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("PYNPUT_BACKEND", "dummy")  # robosuite.devices imports pynput, which wants X
    if args.camera_names:
        use_headless_rendering()

    import veragmil_suite  # noqa: F401  (registers ScoopGranular)

    render = args.render == "on" or (args.render == "auto" and args.device != "scripted" and has_display())
    keep_policy = args.keep or ("success" if args.device == "scripted" else "ask")
    max_attempts = args.max_attempts or (3 * args.episodes + 2 if args.device == "scripted" else None)
    source = "scripted" if args.device == "scripted" else "human"
    operator_name = args.operator or (f"scripted-{args.profile}" if source == "scripted" else "unspecified")
    output = output_path(args)

    env_kwargs = env_kwargs_from_args(args)
    try:
        writer, args.seed = open_writer(
            output,
            env_kwargs,
            args.device,
            operator_name,
            args.seed,
            args.valid_ratio,
            controller=args.controller,
            profile=args.profile if source == "scripted" else "",
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    seeds_problem = seed_span_problem(args.seed, max_attempts or args.episodes, "attempt")
    if seeds_problem:
        writer.close()
        raise UsageError(seeds_problem)

    # the environment is built here in every case: a bad setting is refused before anything is recorded (nothing is
    # written before the first episode), and with workers it settles the piles for them (parallel_attempts)
    operator = None
    cameras = args.camera or args.camera_names[:1] or ["overhead"]
    try:
        env = robosuite.make(
            args.environment,
            **env_kwargs,
            has_renderer=render and args.processes == 1,
            renderer=args.renderer,
            render_camera=cameras[0] if len(cameras) == 1 else cameras,
            seed=args.seed,
        )
    except ValueError as e:
        writer.close()
        raise UsageError(str(e)) from None
    if args.directory is not None:
        os.makedirs(os.path.dirname(output), exist_ok=True)  # robosuite's layout: a new folder per run
    pace = FrameCap(args.max_fr) if args.max_fr is not None else None
    if args.processes > 1 or args.ray is not None:
        attempts = parallel_attempts(env, env_kwargs, args.profile, args.seed, args.success_hold, args.processes,
                                     args.ray)  # fmt: skip
        env = None
    else:
        try:
            operator = make_operator(args, env)
        except SystemExit:
            writer.close()
            raise
        realtime = source == "human" and pace is None
        recorder = EpisodeRecorder(env)
        attempts = local_attempts(env, recorder, operator, args.seed, args.success_hold, render, realtime, pace)
    if not args.quiet:
        workers = f", {args.processes} workers" if args.processes > 1 else ""
        workers = ", on Ray" if args.ray is not None else workers
        print(
            f"recording {args.food} with {args.device} ({operator_name}) into {output}; keep: {keep_policy}" + workers
        )
    teleop = operator if isinstance(operator, TeleopOperator) else None
    try:
        outcome = collect(writer, attempts, args.episodes, keep_policy, max_attempts, operator)
    finally:
        if teleop is not None:
            saved = len(writer.written)
            teleop.close(farewell=f"{saved} demo{'' if saved == 1 else 's'} saved to {output}")
            if not args.quiet and (line := teleop.connection_line()) is not None:
                print(line)
        elif operator is not None:
            operator.close()
        if env is not None:
            env.close()
        writer.close()
    return finish(outcome)


def finish(outcome: CollectionOutcome) -> int:
    """Prints the collection's summary (and why it stopped short, on stderr); returns the exit status: 2 when the
    disk refused a write, 1 when fewer demos were kept than asked, else 0."""
    if (summary := outcome.summary()) is not None:
        print(summary)
    if outcome.failed is not None:
        print(f"veragmil-collect: {outcome.failed}", file=sys.stderr)
        return 2
    if outcome.kept < outcome.requested:
        print(f"veragmil-collect: saved {outcome.kept} of {outcome.requested} requested episodes", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
