"""Steady-state error of the arm controllers: where the spoon comes to rest when a device holds a target pose.

    python benchmarks/bench_controller.py                 # every configuration, 3 s hold per move
    python benchmarks/bench_controller.py --hold-s 5 --configs ours robosuite

A target-holding device (the VR clutch, the scripted expert) sends every step the action that points from the
spoon's pose to its target. The spoon first rises 8 cm clear of the pile, then the target jumps by each move below
(10 cm and 1 cm translations, 10 deg turns) and is held; the error is the distance from the target once the hold
is over. Configurations:

- ours: ScoopGranular's default OSC_POSE (veragmil_suite.controllers.scoop_config.OSC_KP)
- robosuite: robosuite's OSC_POSE defaults (kp=150)
- robosuite-frictionless: the same with the arm's joint friction (frictionloss) set to 0: the cause of its error
- ik: IK_POSE as veragmil_suite.controllers.scoop_config configures it

Run on an otherwise idle machine; the figures do not depend on its speed.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import robosuite
import robosuite.utils.transform_utils as T
from robosuite.controllers import load_part_controller_config

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.controllers.scoop_config import ROBOSUITE_OSC_KP, load_scoop_controller_config
from veragmil_suite.utils import cli

CONFIGS = ("ours", "robosuite", "robosuite-frictionless", "ik")
CLEARANCE_M = 0.08
TURN = np.deg2rad(10.0)
MOVES = {
    "+x 10cm": ([0.1, 0, 0], [0, 0, 0]),
    "-x 10cm": ([-0.1, 0, 0], [0, 0, 0]),
    "+y 10cm": ([0, 0.1, 0], [0, 0, 0]),
    "-y 10cm": ([0, -0.1, 0], [0, 0, 0]),
    "+z 5cm": ([0, 0, 0.05], [0, 0, 0]),
    "-z 5cm": ([0, 0, -0.05], [0, 0, 0]),
    "+x 1cm": ([0.01, 0, 0], [0, 0, 0]),
    "+y 1cm": ([0, 0.01, 0], [0, 0, 0]),
    "-z 1cm": ([0, 0, -0.01], [0, 0, 0]),
    "roll 10deg": ([0, 0, 0], [TURN, 0, 0]),
    "pitch 10deg": ([0, 0, 0], [0, TURN, 0]),
    "yaw 10deg": ([0, 0, 0], [0, 0, TURN]),
}


def controller_config(name: str) -> dict:
    if name == "ik":
        return load_scoop_controller_config("IK_POSE")
    config = load_scoop_controller_config("OSC_POSE")
    if name.startswith("robosuite"):
        stock = load_part_controller_config(default_controller="OSC_POSE")
        assert stock["kp"] == ROBOSUITE_OSC_KP
        config["body_parts"]["right"].update(
            kp=stock["kp"], output_max=stock["output_max"], output_min=stock["output_min"]
        )
    return config


def hold_errors(name: str, hold_s: float, food: str) -> dict[str, tuple[float, float]]:
    """Per move: (position error in mm, orientation error in deg) at the end of the hold."""
    env = robosuite.make(
        "ScoopGranular",
        robots="XArm7",
        food=food,
        controller_configs=controller_config(name),
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        pile_variants=1,
        seed=0,
        hard_reset=False,  # the frictionless variant edits the compiled model, which a hard reset would rebuild
    )
    if name == "robosuite-frictionless":
        env.sim.model.dof_frictionloss[env.robots[0]._ref_joint_vel_indexes] = 0.0
    controller = env.robots[0].part_controllers["right"]
    scale = np.ones(6) if name == "ik" else np.asarray(controller.output_max, dtype=float)
    low, high = env.action_spec
    steps = int(round(hold_s * env.control_freq))
    errors = {}
    for move, (dp, drot) in MOVES.items():
        obs = env.reset()
        start_pos, start_rot = obs["robot0_eef_pos"].copy(), T.quat2mat(obs["robot0_eef_quat"])
        clear = start_pos + [0.0, 0.0, CLEARANCE_M]
        target_rot = T.quat2mat(T.axisangle2quat(np.asarray(drot, dtype=float))) @ start_rot
        for target_pos, rot in ((clear, start_rot), (clear + dp, target_rot)):
            for _ in range(steps):
                pos_err = target_pos - obs["robot0_eef_pos"]
                rot_err = T.quat2axisangle(T.mat2quat(rot @ T.quat2mat(obs["robot0_eef_quat"]).T))
                obs, _, _, _ = env.step(np.clip(np.concatenate([pos_err, rot_err]) / scale, low, high))
        pos_err = np.linalg.norm(target_pos - obs["robot0_eef_pos"])
        rot_err = np.linalg.norm(T.quat2axisangle(T.mat2quat(rot @ T.quat2mat(obs["robot0_eef_quat"]).T)))
        errors[move] = (1000.0 * pos_err, float(np.degrees(rot_err)))
    env.close()
    return errors


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_controller.py", description=__doc__)
    parser.add_argument(
        "--configs",
        type=cli.ListOf(cli.Choice("controller configuration", CONFIGS)),
        default=list(CONFIGS),
        help="the configurations compared",
    )
    parser.add_argument("--hold-s", type=cli.positive, default=3.0, help="seconds each target is held")
    parser.add_argument("--food", type=cli.food, default="barley", help="the pile under the spoon (it is not touched)")
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Each configuration's error after each move, and the worst of each."""
    results = {name: hold_errors(name, args.hold_s, args.food) for name in args.configs}
    width = max(len(m) for m in MOVES)
    print(f"position error (mm) / orientation error (deg) after a {args.hold_s:g} s hold")
    print(f"{'move':<{width}}" + "".join(f" {name:>24}" for name in args.configs))
    for move in MOVES:
        cells = "".join(f" {results[n][move][0]:>14.2f} / {results[n][move][1]:>5.2f}" for n in args.configs)
        print(f"{move:<{width}}{cells}")
    print(
        f"{'max':<{width}}"
        + "".join(
            f" {max(e[0] for e in results[n].values()):>14.2f} / {max(e[1] for e in results[n].values()):>5.2f}"
            for n in args.configs
        )
    )
    if "ours" in results and "robosuite" in results:
        ours = max(e[0] for e in results["ours"].values())
        stock = max(e[0] for e in results["robosuite"].values())
        print(f"\nworst position error: ours {ours:.2f} mm, robosuite's defaults {stock:.2f} mm ({stock / ours:.1f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
