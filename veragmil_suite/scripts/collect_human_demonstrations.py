"""
Collect ScoopGranular demonstrations straight into a robomimic HDF5 file.

Devices: ``keyboard`` and ``spacemouse`` (robosuite's own device classes), ``vr`` (a WebXR headset,
veragmil_suite.devices.VRDevice) and ``scripted`` (the scripted expert, veragmil_suite.expert: no human, no
display, no prompt). After each episode its metrics (success, spilled pieces and volume, completion time) are
printed and stored, and the operator keeps or discards it; discarded attempts are still logged, so a human
operator's success rate counts every attempt (the paper's "Human" column).

Each kept episode is flushed to the file when it ends: stopping the script (Ctrl-C, or killing it) loses at most
the episode in progress. Giving an existing file appends to it.

Attempt k (from 0) resets the environment with seed ``--seed`` + k (and seeds the scripted expert with it), so an
episode depends on its seed alone. The scripted device can record in ``--workers`` processes, or as Ray tasks with
``--ray [ADDRESS]`` (on the piles settled here): attempts run in parallel and are kept or discarded in seed order,
so the file is the same for any number of workers, wherever they run.

Example:
    veragmil-collect --device scripted --food rice --episodes 2 --output out.hdf5
    veragmil-collect --device keyboard --food pasta --episodes 30 --output pasta_keyboard.hdf5 --operator alice
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import os
import sys
import time

import numpy as np

from veragmil_suite.distributed import add_ray_argument, check_ray_argument
from veragmil_suite.episode import SUCCESS_HOLD_S, run_until_done
from veragmil_suite.scripts.cli import port, positive_int

DEVICES = ("keyboard", "spacemouse", "vr", "scripted")
KEEP_POLICIES = ("ask", "all", "success")


def build_parser() -> argparse.ArgumentParser:
    from veragmil_suite.expert import PROFILES
    from veragmil_suite.foods import FOODS

    p = argparse.ArgumentParser(
        prog="veragmil-collect",
        description=__doc__.split("\n\n")[0].strip() + " Devices: keyboard, spacemouse, vr, scripted.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--device", choices=DEVICES, default="keyboard", help="who drives the spoon")
    p.add_argument("--food", choices=sorted(FOODS), default="rice")
    p.add_argument("--episodes", type=int, default=1, help="demonstrations to save")
    p.add_argument("--output", required=True, help="HDF5 file (appended to when it exists)")
    p.add_argument(
        "--robot",
        default="XArm7",
        help="robosuite robot with the spoon: a single arm, or the Unitree G1 (G1FixedLowerBody, G1ArmsOnly; "
        "needs robosuite-models, the package's humanoid extra)",
    )
    p.add_argument(
        "--controller",
        default="OSC_POSE",
        help="OSC_POSE, or a robosuite composite-controller JSON file whose arm is OSC_POSE (other gains); every "
        "device and the expert send OSC_POSE deltas (robosuite's devices support no IK_POSE)",
    )
    p.add_argument("--control-freq", type=int, default=20, help="control rate, Hz (the paper's VR runs at 60)")
    p.add_argument("--horizon", type=positive_int, default=400, help="longest episode, control steps")
    p.add_argument("--n-grains", type=positive_int, default=None, help="grains in the bowl (default: the food's own)")
    p.add_argument(
        "--cameras", nargs="*", default=["overhead"], help="cameras recorded as <name>_image; none: low-dim only"
    )
    p.add_argument("--camera-size", type=positive_int, nargs="+", default=[84], metavar="PX", help="height [width]")
    p.add_argument("--depth", action="store_true", help="also record <camera>_depth (metres)")
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="attempt k runs with seed SEED + k (env and scripted expert); default 0, or when appending, the seed "
        "after the file's last",
    )
    p.add_argument(
        "--workers",
        type=positive_int,
        default=1,
        help="scripted device: parallel recording processes (same file for any N)",
    )
    p.add_argument(
        "--keep",
        choices=KEEP_POLICIES,
        default=None,
        help="which episodes to save: ask the operator, all, or the successful ones "
        "(default: success for scripted, ask otherwise)",
    )
    p.add_argument(
        "--max-attempts", type=int, default=None, help="stop after this many episodes (default: 3x --episodes + 2 "
        "for scripted, unlimited otherwise)"
    )  # fmt: skip
    p.add_argument(
        "--success-hold",
        type=float,
        default=SUCCESS_HOLD_S,
        help="end an episode once success held this long, s",
    )
    p.add_argument("--operator", default=None, help="who demonstrates (stored with every demo)")
    p.add_argument("--profile", choices=sorted(PROFILES), default="expert", help="scripted operator profile")
    p.add_argument("--valid-ratio", type=float, default=0.1, help="fraction of demos in mask/valid")
    p.add_argument(
        "--render", choices=("auto", "on", "off"), default="auto", help="live window (auto: for humans with a display)"
    )
    p.add_argument("--pos-sensitivity", type=float, default=1.0, help="keyboard / spacemouse / vr translation scale")
    p.add_argument("--rot-sensitivity", type=float, default=1.0, help="keyboard / spacemouse / vr rotation scale")
    p.add_argument("--vr-host", default="127.0.0.1", help="VR server address (0.0.0.0 for a Wi-Fi headset)")
    p.add_argument("--vr-port", type=port, default=8765)
    p.add_argument(
        "--vr-allow-emulated",
        action="store_true",
        help="vr: drive with poses the headset only estimates (WebXR emulatedPosition: a controller out of the "
        "cameras' view, or a desktop emulator such as iwer, which marks every pose so); off: they release the grip",
    )
    p.add_argument("--quiet", action="store_true", help="print only the per-episode lines and the summary")
    add_ray_argument(p, "the scripted attempts")
    return p


def env_kwargs_from_args(args) -> dict:
    """robosuite.make keyword arguments (besides the env name) for the command line, JSON-serializable."""
    height, width = (args.camera_size * 2)[:2]
    kwargs = dict(
        robots=args.robot,
        food=args.food,
        controller_configs=controller_config(args.controller, args.robot),
        control_freq=args.control_freq,
        horizon=args.horizon,
        ignore_done=False,
        reward_shaping=False,
        use_object_obs=True,
        use_camera_obs=bool(args.cameras),
        has_offscreen_renderer=bool(args.cameras),
        camera_names=list(args.cameras) if args.cameras else "overhead",
        camera_heights=height,
        camera_widths=width,
        camera_depths=bool(args.depth),
    )
    if args.n_grains is not None:
        kwargs["n_grains"] = args.n_grains
    return kwargs


def controller_config(value: str, robot: str) -> dict:
    """The composite controller config for ``--controller``: our OSC_POSE default or a JSON file with an OSC arm."""
    from veragmil_suite.controllers import ARM_CONTROLLERS, load_scoop_controller_config

    if value == "OSC_POSE":
        return load_scoop_controller_config("OSC_POSE", robot=robot)
    if value in ARM_CONTROLLERS:
        raise SystemExit(
            f"veragmil-collect: collection needs OSC_POSE deltas; robosuite's devices and the scripted expert do not "
            f"drive {value}"
        )
    try:
        with open(value) as f:
            config = json.load(f)
    except (OSError, ValueError) as e:
        raise SystemExit(
            f"veragmil-collect: --controller {value!r} is neither OSC_POSE nor a readable JSON file ({e})"
        ) from None
    arm = config.get("body_parts", {}).get("right", {}) if isinstance(config, dict) else {}
    if arm.get("type") != "OSC_POSE":
        raise SystemExit(
            f"veragmil-collect: {value} drives the arm with {arm.get('type')!r}; collection needs OSC_POSE deltas"
        )
    return config


# ---------------------------------------------------------------------------------------------------------------- #
# Operators: who produces the actions                                                                              #
# ---------------------------------------------------------------------------------------------------------------- #


class ScriptedOperator:
    """The scripted expert as an operator: never asks, never needs a display."""

    source = "scripted"

    def __init__(self, env, profile: str, seed: int):
        from veragmil_suite.expert import ScriptedScooper

        self.expert = ScriptedScooper(env, profile, seed=seed)
        self.name = f"scripted-{self.expert.profile.name}"
        self.command = None
        self.label = None

    def begin(self, seed: int | None = None) -> None:
        self.expert.reset(seed=seed)
        self.command = None

    def action(self, obs: dict) -> np.ndarray | None:
        """The action to execute; ``label`` is the one to record (they differ under injected noise)."""
        if self.expert.done:
            return None
        self.label = self.expert.act(obs)
        return self.expert.executed(self.label)

    def close(self) -> None:
        pass


class TeleopOperator:
    """A robosuite Device (keyboard, SpaceMouse, VR) as an operator."""

    source = "human"

    def __init__(self, env, device, name: str):
        self.env = env
        self.device = device
        self.name = name
        self.command = None
        self.label = None  # the action executed is the one recorded

    def begin(self, seed: int | None = None) -> None:
        self.command = None
        self.ended = False
        self.device.start_control()
        if hasattr(self.device, "engaged"):
            # a clutched device (VR): the episode starts at the operator's first squeeze; until then the robot
            # stands still and nothing is recorded or counted against the horizon
            self.device.status_message = "squeeze the grip to start"
            while not self.device.engaged:
                if self.device.input2action() is None:  # keep, discard or reset before starting: an empty episode
                    self.command = getattr(self.device, "episode_command", None) or "reset"
                    self.ended = True
                    return
                time.sleep(self.env.control_timestep)
            self.device.status_message = ""
        if hasattr(self.device, "recording"):
            self.device.recording = True

    def action(self, obs: dict) -> np.ndarray | None:
        if self.ended:
            return None
        action_dict = self.device.input2action()
        if action_dict is None:
            self.command = getattr(self.device, "episode_command", None) or "reset"
            return None
        robot = self.env.robots[0]
        arm = robot.arms[0]
        controller = robot.part_controllers[arm]
        key = f"{arm}_delta" if getattr(controller, "input_type", "delta") == "delta" else f"{arm}_abs"
        return robot.create_action_vector({arm: action_dict[key]})

    def wait_for_verdict(self) -> str | None:
        """VR: after an episode ended by itself, wait for the operator's keep or discard button."""
        if not hasattr(self.device, "request_episode_end"):
            return None
        self.device.status_message = "press keep or discard"
        self.device.start_control()
        while self.device.input2action() is not None:
            time.sleep(0.02)
        return self.device.episode_command

    def end(self) -> None:
        if hasattr(self.device, "recording"):
            self.device.recording = False

    def show_progress(self, text: str) -> None:
        """The collection's state on the device's status line, where it has one (VR)."""
        if hasattr(self.device, "progress"):
            self.device.progress = text

    def close(self, farewell: str | None = None) -> None:
        if hasattr(self.device, "progress"):
            self.device.close(farewell=farewell)
        elif hasattr(self.device, "close"):
            self.device.close()

    def connection_line(self) -> str | None:
        """VR: the server's non-zero counters (vr_server.COUNTERS), so that a session whose page reconnected or was
        dropped as silent says so after the fact."""
        if not hasattr(self.device, "stats"):
            return None
        counts = [f"{name} {n}" for name, n in self.device.stats()["server"].items() if n]
        return "vr server: " + (", ".join(counts) or "no page connected")


def make_operator(args, env):
    """The operator for ``--device``; a clear SystemExit when its hardware or display is missing."""
    if args.device == "scripted":
        return ScriptedOperator(env, args.profile, args.seed)
    if args.device == "keyboard":
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise SystemExit("veragmil-collect: keyboard teleoperation needs a display (no DISPLAY is set)")
        from robosuite.devices import Keyboard

        device = Keyboard(env=env, pos_sensitivity=args.pos_sensitivity, rot_sensitivity=args.rot_sensitivity)
    elif args.device == "spacemouse":
        from robosuite.devices import SpaceMouse

        try:
            device = SpaceMouse(env=env, pos_sensitivity=args.pos_sensitivity, rot_sensitivity=args.rot_sensitivity)
        except (OSError, ImportError) as e:
            raise SystemExit(f"veragmil-collect: no SpaceMouse found through hidapi ({e})") from None
    else:
        from veragmil_suite.devices import VRDevice, VRServerOptions

        device = VRDevice(
            env,
            server=VRServerOptions(host=args.vr_host, port=args.vr_port),
            pos_sensitivity=args.pos_sensitivity,
            rot_sensitivity=args.rot_sensitivity,
            allow_emulated_position=args.vr_allow_emulated,
            verbose=not args.quiet,
        )
    return TeleopOperator(env, device, args.operator or "")


# ---------------------------------------------------------------------------------------------------------------- #
# The collection loop                                                                                              #
# ---------------------------------------------------------------------------------------------------------------- #


def run_episode(
    env, recorder, operator, success_hold_s: float, render: bool, realtime: bool, seed: int | None = None
) -> str:
    """Record one episode (env and operator seeded with ``seed``) through the shared episode loop
    (veragmil_suite.episode); returns why it ended: "success", "horizon", "operator" (a human stopped), "gave up"
    (the scripted operator did) or "physics". A ``success_hold_s`` <= 0 leaves success out of the ending rule."""
    obs = recorder.reset(seed=seed)
    operator.begin(seed=seed)
    end = run_until_done(
        operator.action,
        lambda action: recorder.step(action, label=operator.label),
        obs,
        env.control_freq,
        env.horizon,
        success_hold_s=success_hold_s,
        on_step=env.render if render else None,
        realtime=realtime,
        stopped="operator" if operator.source == "human" else "gave up",
    )
    return end.reason


def record_attempt(env, recorder, operator, args, seed: int, render: bool = False, realtime: bool = False):
    """One attempt with ``seed``: (seed, why it ended, the Episode, or None when no step was taken)."""
    reason = run_episode(env, recorder, operator, args.success_hold, render, realtime, seed=seed)
    if not recorder.num_steps:
        return seed, reason, None
    return seed, reason, recorder.episode(attrs=dict(end_reason=reason, pile_variant=int(env.pile_variant), seed=seed))


def local_attempts(env, recorder, operator, args, render: bool, realtime: bool):
    """Attempts in this process, one at a time, seeds SEED, SEED + 1, ...: yields record_attempt's tuples."""
    seed = args.seed
    while True:
        yield record_attempt(env, recorder, operator, args, seed, render, realtime)
        seed += 1


_WORKER: dict = {}  # per recording worker process: its env, recorder and operator, and the settings they were built for


def _ignore_sigint() -> None:
    """Local recording workers leave Ctrl-C to the parent, which stops the pool."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_attempt(context: tuple, seed: int):
    """One attempt in a recording worker, whose env and scripted operator are built at its first attempt.
    ``context``: (arguments, env kwargs, the driver's settled piles or None)."""
    import robosuite

    import veragmil_suite  # noqa: F401
    from veragmil_suite import recording, settling

    args, env_kwargs, piles = context
    settling.use_shipped_piles(piles)
    settings = json.dumps([vars(args), env_kwargs], sort_keys=True, default=str)
    if _WORKER.get("settings") != settings:
        if "env" in _WORKER:
            _WORKER["env"].close()
        env = robosuite.make("ScoopGranular", **env_kwargs, has_renderer=False, seed=args.seed)
        operator = ScriptedOperator(env, args.profile, args.seed)
        _WORKER.update(env=env, recorder=recording.EpisodeRecorder(env), operator=operator, settings=settings)
    return record_attempt(_WORKER["env"], _WORKER["recorder"], _WORKER["operator"], args, seed)


def parallel_attempts(args, env_kwargs: dict, piles: dict | None = None):
    """
    Scripted attempts in ``args.workers`` processes, or as Ray tasks (``args.ray``) on the driver's settled
    ``piles``, yielded in seed order like local_attempts (a few attempts run ahead; those not needed are cancelled
    or dropped when the caller stops).
    """
    from veragmil_suite.distributed import ray_session, run_pieces

    with ray_session(args.ray) as address:
        on_ray = address is not None
        attempts = run_pieces(
            _worker_attempt,
            itertools.count(args.seed),
            context=(args, env_kwargs, piles),
            processes=args.workers,
            on_ray=on_ray,
            ordered=True,
            setup=None if on_ray else _ignore_sigint,
        )
        with contextlib.closing(attempts):
            for _, attempt in attempts:
                yield attempt


def ask_keep(prompt: str) -> bool:
    while True:
        try:
            answer = input(prompt).strip().lower()
        except EOFError:
            return False
        if answer in ("", "y", "yes"):
            return True
        if answer in ("n", "no"):
            return False


def episode_line(n: int, metrics: dict, steps: int, reason: str) -> str:
    m = metrics
    line = (
        f"episode {n}: {'SUCCESS' if m['success'] else 'failure'} ({reason}), {steps} steps; "
        f"in spoon {m['grains_in_spoon']} ({m['spoon_volume_cm3']:.2f} cm3); "
        f"spilled {m['grains_spilled']} pieces, {m['spilled_volume_cm3']:.2f} cm3 "
        f"({100 * m['spill_fraction']:.1f}% of scooped); time {m['completion_time_s']:.2f} s"
    )
    return line + (f"; physics: {m['physics_error']}" if m["physics_error"] else "")


def main(argv: list[str] | None = None) -> int:
    """veragmil-collect: record demonstrations (see --help)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.episodes < 1:
        raise SystemExit("veragmil-collect: --episodes must be at least 1")
    if args.workers < 1:
        raise SystemExit(f"veragmil-collect: --workers must be at least 1, got {args.workers}")
    if args.workers > 1 and args.device != "scripted":
        raise SystemExit(
            f"veragmil-collect: --workers {args.workers} needs --device scripted (one person drives one device)"
        )
    if args.ray is not None and args.device != "scripted":
        raise SystemExit("veragmil-collect: --ray needs --device scripted (one person drives one device)")
    check_ray_argument(parser, args)
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("PYNPUT_BACKEND", "dummy")  # robosuite.devices imports pynput, which wants X
    if args.cameras:
        from veragmil_suite.rendering import use_headless_rendering

        use_headless_rendering()

    import robosuite

    import veragmil_suite  # noqa: F401  (registers ScoopGranular)
    from veragmil_suite import recording

    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    render = args.render == "on" or (args.render == "auto" and args.device != "scripted" and has_display)
    keep_policy = args.keep or ("success" if args.device == "scripted" else "ask")
    max_attempts = args.max_attempts or (3 * args.episodes + 2 if args.device == "scripted" else None)
    source = "scripted" if args.device == "scripted" else "human"
    operator_name = args.operator or (f"scripted-{args.profile}" if source == "scripted" else "unspecified")

    env_kwargs = env_kwargs_from_args(args)
    try:
        writer = recording.DemoWriter(
            args.output,
            recording.env_meta(env_kwargs),
            recording.provenance(
                device=args.device,
                operator=operator_name,
                food=args.food,
                robot=args.robot,
                source=source,
                controller=args.controller,
                control_freq=args.control_freq,
                env_seed=args.seed,
                profile=args.profile if source == "scripted" else "",
            ),
            valid_ratio=args.valid_ratio,
        )
    except recording.DatasetError as e:
        print(f"veragmil-collect: {e}", file=sys.stderr)
        return 2
    last = max(writer.seeds_used, default=None)
    if args.seed is None:
        args.seed = 0 if last is None else last + 1
    elif last is not None and args.seed <= last:
        writer.close()
        print(
            f"veragmil-collect: {args.output} already holds attempts with seeds up to {last} (attempt k runs with "
            f"seed SEED + k, and a seed gives the same episode again): --seed {args.seed} would repeat them; omit "
            f"--seed to continue from {last + 1}, or pass a seed above {last}",
            file=sys.stderr,
        )
        return 2
    writer.provenance["env_seed"] = args.seed

    # the environment is built here in every case: a bad setting is refused before anything is recorded (nothing is
    # written before the first episode), and with workers it settles the piles: local workers read them from the
    # disk cache, Ray workers are handed them
    operator = None
    try:
        env = robosuite.make(
            "ScoopGranular",
            **env_kwargs,
            has_renderer=render and args.workers == 1,
            render_camera=args.cameras[0] if args.cameras else "overhead",
            seed=args.seed,
        )
    except ValueError as e:
        writer.close()
        print(f"veragmil-collect: {e}", file=sys.stderr)
        return 2
    if args.workers > 1 or args.ray is not None:
        piles = env.settled_piles() if args.ray is not None else None
        env.close()
        env = None
        attempts_iter = parallel_attempts(args, env_kwargs, piles)
    else:
        try:
            operator = make_operator(args, env)
        except SystemExit:
            writer.close()
            raise
        recorder = recording.EpisodeRecorder(env)
        attempts_iter = local_attempts(env, recorder, operator, args, render, realtime=source == "human")
    kept, attempts, results = 0, 0, []
    if not args.quiet:
        workers = f", {args.workers} workers" if args.workers > 1 else ""
        workers = ", on Ray" if args.ray is not None else workers
        print(
            f"recording {args.food} with {args.device} ({operator_name}) into {args.output}; keep: {keep_policy}"
            + workers
        )
    teleop = operator if isinstance(operator, TeleopOperator) else None
    discarded = 0
    failed = None  # the write the disk refused: the collection stops there
    try:
        while kept < args.episodes and (max_attempts is None or attempts < max_attempts):
            if teleop is not None:
                teleop.show_progress(
                    f"episode {attempts + 1} | kept {kept}/{args.episodes} | discarded {discarded} | "
                    f"{os.path.basename(args.output)}"
                )
            seed, reason, episode = next(attempts_iter)
            attempts += 1
            if episode is None:
                continue
            episode.attrs["attempt"] = attempts
            metrics = episode.metrics
            print(episode_line(attempts, metrics, episode.num_samples, reason), flush=True)
            command = operator.command if operator is not None else None
            if keep_policy == "ask" and command not in ("keep", "discard", "reset"):
                verdict = operator.wait_for_verdict() if isinstance(operator, TeleopOperator) else None
                command = verdict or ("keep" if ask_keep("keep this episode? [Y/n] ") else "discard")
            keep = {
                "all": True,
                "success": bool(metrics["success"]),
                "ask": command == "keep",
            }[keep_policy]
            if isinstance(operator, TeleopOperator):
                operator.end()
            results.append(metrics)
            try:
                if keep:
                    name = writer.write(episode)
                else:
                    writer.log_discarded(metrics, attrs=dict(attempt=attempts, end_reason=reason, seed=seed))
            except recording.DatasetError as e:
                failed = f"{e}: episode {attempts} (seed {seed}) is not saved; all saved before it are ({kept} here)"
                break
            if keep:
                kept += 1
                print(f"  saved as {name} ({kept}/{args.episodes})", flush=True)
            else:
                discarded += 1
                print("  discarded", flush=True)
    except KeyboardInterrupt:
        kept = len(writer.written)
        print(f"\ninterrupted: the episode in progress is dropped; {kept} episodes saved to {args.output}")
    finally:
        attempts_iter.close()
        if teleop is not None:
            saved = len(writer.written)
            teleop.close(farewell=f"{saved} demo{'' if saved == 1 else 's'} saved to {args.output}")
            if not args.quiet and (line := teleop.connection_line()) is not None:
                print(line)
        elif operator is not None:
            operator.close()
        if env is not None:
            env.close()
        writer.close()
    _print_summary(results, kept, args.output)
    if failed is not None:
        print(f"veragmil-collect: {failed}", file=sys.stderr)
        return 2
    if kept < args.episodes:
        print(f"veragmil-collect: saved {kept} of {args.episodes} requested episodes", file=sys.stderr)
        return 1
    return 0


def _print_summary(results: list[dict], kept: int, path: str) -> None:
    if not results:
        return
    success = np.mean([r["success"] for r in results])
    spill = np.mean([r["grains_spilled"] for r in results])
    spill_vol = np.mean([r["spilled_volume_cm3"] for r in results])
    times = [r["completion_time_s"] for r in results if r["success"]]
    print(
        f"{len(results)} attempts, {kept} saved to {path}: success {100 * success:.0f}%, "
        f"spilled {spill:.1f} pieces ({spill_vol:.2f} cm3) on average"
        + (f", completion {np.mean(times):.2f} s on success" if times else "")
    )


if __name__ == "__main__":
    sys.exit(main())
