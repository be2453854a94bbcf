"""ScoopGranular: scoop granular food from a bowl with a spoon and carry it to a post-scoop pose without spilling."""

from __future__ import annotations

import functools
import re
import warnings

import mujoco
import numpy as np
import robosuite.utils.transform_utils as T
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv
from robosuite.utils.mjcf_utils import array_to_string, find_elements, new_element
from robosuite.utils.observables import Observable, sensor

from veragmil_suite.controllers.fast_control import use_block_mass_matrix
from veragmil_suite.controllers.scoop_config import (
    UntunedControllerWarning,
    leave_heading_free,
    load_scoop_controller_config,
    untuned_controller_difference,
)
from veragmil_suite.environments.settling import SettledPile, pile_key, settle
from veragmil_suite.models.arena import ScoopArena
from veragmil_suite.models.bowl import DEFAULT_BOWL_SHAPE, Bowl
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import DEFAULT_PHYSICS, FOODS, PHYSICS, FoodSpec, GrainModel, check_physics, get_food
from veragmil_suite.models.grains import GrainPile
from veragmil_suite.models.humanoid import (
    SPOON_ARM,
    HumanoidLayout,
    check_robot,
    humanoid_layout,
    self_contact_excludes,
)
from veragmil_suite.models.scoop_task import (
    GRAIN_SLEEP_TOLERANCE,
    PHYSICS_SOLVER_OPTIONS,
    PHYSICS_TIMESTEP_S,
    ScoopTask,
    check_physics_timestep,
    check_sleep_tolerance,
)
from veragmil_suite.models.spoon_gripper import SPOON_SHAPE, spoon_contact
from veragmil_suite.utils.kinematics import solve_pose_ik
from veragmil_suite.utils.sim_xml import keep_sim_xml

M3_PER_CM3 = 1e-6
# the largest grain count accepted, as a multiple of the food's default (veragmil_suite.scripts.bench times 1x, 2x and
# 4x)
MAX_GRAINS_PER_DEFAULT = 4
# pile variants tried when a loaded model's pile is identified (beyond the environment's own pile_variants)
LOADED_PILE_VARIANTS_TRIED = 64
# the slowest control rate accepted: a control period longer than a second is neither teleoperation nor a policy,
# and robosuite runs period / physics step substeps per control step (control_freq=1e-9 would never return)
MIN_CONTROL_FREQ_HZ = 1.0

# Spoon orientations in the world, as rotation matrices of the flange (eef) frame. Pre-scoop: the tool points
# straight down, so the bent spoon's tip points down at 45 degrees along +x (away from the robot), its bowl
# facing up and forward. Post-scoop: the same turned 45 degrees about y, so the spoon's bowl is level.
PRE_SCOOP_EEF_ROT = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
_LEVEL_TURN = T.quat2mat(T.axisangle2quat(np.array([0.0, -np.pi / 4, 0.0])))
POST_SCOOP_EEF_ROT = _LEVEL_TURN @ PRE_SCOOP_EEF_ROT

# How far a scoop got, in order; a state's stage comes from the simulator state alone (ScoopGranular.scoop_stage),
# so any agent's episode is labelled the same way: its furthest stage, and "held" once success has held.
SCOOP_STAGES = ("start", "reached pile", "loaded spoon", "lifted clear", "at post-scoop pose", "held")


class ScoopGranular(ManipulationEnv):
    """
    This class corresponds to scooping granular food (rice, buckwheat, barley, pasta, peas, beans, flakes) from a
    bowl with a spoon, and carrying the spoonful to a post-scoop pose without spilling, for a single robot arm.

    Args:
        robots (str or list of str): Specification for specific robot arm to be instantiated within this env
            (e.g: "XArm7"). Note: Must be a single single-arm robot, or the Unitree G1 ("G1FixedLowerBody",
            "G1ArmsOnly", with robosuite-models), which the task places at the table (veragmil_suite.models.humanoid):
            it scoops with its right hand, and its left arm and torso hold still. Default: XArm7.
        env_configuration (str): Specifies how to position the robots within the environment (default is "default").
        controller_configs (str or dict): composite controller config. None gives OSC_POSE (see
            veragmil_suite.controllers.scoop_config.load_scoop_controller_config, which also offers robosuite's
            IK_POSE); any other config (robosuite's own defaults among them) is warned about once, naming what differs
            (UntunedControllerWarning).
        gripper_types (str): end-effector; default "SpoonGripper" (a two-armed robot holds it in its right hand and
            nothing in its left)
        base_types (str): robot base type; "default" uses the robot's own
        initialization_noise (dict or "default"): joint noise of the initial (pre-scoop) configuration
        food (str or FoodSpec): a catalog food name (veragmil_suite.models.foods.FOODS) or a custom FoodSpec
        physics (str): "calibrated" (default: grains calibrated against measurements of the real foods) or "table1"
            (the paper's Table I parameters, as every result before calibration); veragmil_suite.models.foods.PHYSICS
        n_grains (None or int): grains in the bowl; None uses the food's default (a scoopable real-time scene)
        pile_variants (int): distinct piles (grain sizes and arrangement) drawn from per reset; each is settled
            once per machine and cached (veragmil_suite.environments.settling)
        bowl_shape (DishShape): dimensions of the bowl
        bowl_x_range (2-tuple): bowl position range along x (m, relative to its nominal place)
        bowl_y_range (2-tuple): bowl position range along y (m, relative to its nominal place)
        pre_scoop_offset (3-array): start position of the spoon relative to the bowl's rim centre (m)
        post_scoop_offset (3-array): goal position of the spoon relative to the bowl's rim centre (m)
        success_pos_tolerance (float): spoon within this distance of the post-scoop position (m)
        success_tilt_tolerance_deg (float): spoon's bowl within this angle of level
        success_max_speed (float): spoon slower than this (m/s), i.e. held at the pose
        min_portion_fraction (float): food the spoon must carry for success, as a fraction of the food in the bowl
            (by volume: 5% is ~10 grains of rice, 2 pieces of pasta)
        min_portion_cm3 (None or float): an absolute portion (cm^3) instead of min_portion_fraction
        max_spill_fraction (float): spilled volume must stay under this fraction of the volume scooped
        table_full_size (3-tuple): x, y, and z dimensions of the table
        use_camera_obs (bool): if True, every observation includes rendered image(s)
        use_object_obs (bool): if True, include task information (desired pose, bowl, spoon load) in the
            observation
        use_food_params_obs (bool): if True, add the food's physical parameters to the object observations
            (off by default so results on unseen foods stay honest)
        reward_scale (None or float): Scales the normalized reward function by the amount specified
        reward_shaping (bool): if True, use dense rewards
        fast_rendering (bool): no anti-aliasing, shadows or fine tessellation (software rendering is 40x faster)
        sleep_tolerance (None or float): grains (any body at rest) sleep under this velocity tolerance, MuJoCo's
            island sleeping (veragmil_suite.models.scoop_task.GRAIN_SLEEP_TOLERANCE); None: nothing sleeps
        physics_solver_options (None or dict): MuJoCo <option> attributes for the pile (default: CG, elliptic)
        physics_timestep_s (float): the physics step (s), a whole number of them per control period (default
            veragmil_suite.models.scoop_task.PHYSICS_TIMESTEP_S, 1/240 s). A recorded XML loaded later
            (reset_from_xml_string) runs at the step it was recorded with.
        A model loaded with reset_from_xml_string (any ScoopGranular XML a tool saved, MuJoCo's rounded numbers
        included) brings its own food, grain count, pile and physics step: the environment adopts them until its
        next fresh model, which is of the food and grain count given here again.
        (robosuite's usual arguments: has_renderer, has_offscreen_renderer, render_camera, render_collision_mesh,
        render_visual_mesh, render_gpu_device_id, control_freq, lite_physics, horizon, ignore_done, hard_reset,
        camera_names, camera_heights, camera_widths, camera_depths, camera_segmentations, renderer,
        renderer_config, seed)

    Raises:
        ValueError: [Unknown food, invalid sizes or ranges]
    """

    def __init__(
        self,
        robots="XArm7",
        env_configuration="default",
        controller_configs=None,
        gripper_types="SpoonGripper",
        base_types="default",
        initialization_noise="default",
        food="rice",
        physics=DEFAULT_PHYSICS,
        n_grains=None,
        pile_variants=4,
        bowl_shape: DishShape = DEFAULT_BOWL_SHAPE,
        bowl_x_range=(-0.02, 0.02),
        bowl_y_range=(-0.02, 0.02),
        pre_scoop_offset=(-0.03, 0.0, 0.06),
        post_scoop_offset=(-0.05, 0.12, 0.12),
        success_pos_tolerance=0.03,
        success_tilt_tolerance_deg=20.0,
        success_max_speed=0.05,
        min_portion_fraction=0.05,
        min_portion_cm3=None,
        max_spill_fraction=0.05,
        table_full_size=(0.8, 0.8, 0.05),
        use_camera_obs=True,
        use_object_obs=True,
        use_food_params_obs=False,
        reward_scale=1.0,
        reward_shaping=False,
        fast_rendering=True,
        sleep_tolerance=GRAIN_SLEEP_TOLERANCE,
        physics_solver_options=None,
        physics_timestep_s=PHYSICS_TIMESTEP_S,
        has_renderer=False,
        has_offscreen_renderer=True,
        render_camera="agentview",
        render_collision_mesh=False,
        render_visual_mesh=True,
        render_gpu_device_id=-1,
        control_freq=20,
        lite_physics=True,
        horizon=400,
        ignore_done=False,
        hard_reset=True,
        camera_names="overhead",
        camera_heights=84,
        camera_widths=84,
        camera_depths=False,
        camera_segmentations=None,
        renderer="mjviewer",
        renderer_config=None,
        seed=None,
    ):
        self.food: FoodSpec = get_food(food)
        self.physics = check_physics(physics)
        self.grain: GrainModel = self.food.grain(self.physics)
        for robot in [robots] if isinstance(robots, str) else list(robots):
            check_robot(robot)
        robot_name = robots if isinstance(robots, str) else robots[0]
        self.humanoid: HumanoidLayout | None = humanoid_layout(robot_name)
        if self.humanoid is not None and isinstance(gripper_types, str):
            gripper_types = [[gripper_types, None]]  # per arm (right, left) of the one robot
        if n_grains is not None and (not isinstance(n_grains, (int, np.integer)) or n_grains <= 0):
            raise ValueError(f"n_grains must be a positive integer or None (the food's default), got {n_grains!r}")
        self.n_grains = int(n_grains) if n_grains is not None else self.grain.default_grains
        # food, physics and n_grains are the simulation's (a loaded model's may differ); these are what fresh
        # models get
        self._env_food, self._env_physics, self._env_n_grains = self.food, self.physics, self.n_grains
        limit = MAX_GRAINS_PER_DEFAULT * self.grain.default_grains
        if self.n_grains > limit:
            raise ValueError(
                f"n_grains {self.n_grains} is more than a bowl of {self.food.name} settles in reasonable time: at most "
                f"{limit} ({MAX_GRAINS_PER_DEFAULT}x its default of {self.grain.default_grains})"
            )
        if int(pile_variants) < 1:
            raise ValueError(f"pile_variants must be at least 1, got {pile_variants!r}")
        self.pile_variants = int(pile_variants)
        for label, rng_range in (("bowl_x_range", bowl_x_range), ("bowl_y_range", bowl_y_range)):
            if len(rng_range) != 2 or rng_range[0] > rng_range[1]:
                raise ValueError(f"{label} must be (low, high) with low <= high, got {rng_range!r}")
        if (
            isinstance(control_freq, bool)
            or not isinstance(control_freq, (int, float))
            or not (MIN_CONTROL_FREQ_HZ <= control_freq < float("inf"))
        ):
            raise ValueError(
                f"control_freq must be a number of Hz of at least {MIN_CONTROL_FREQ_HZ:g} (20 Hz default, 60 Hz as in "
                f"the paper), got {control_freq!r}"
            )
        self.bowl_shape = bowl_shape
        self.bowl_x_range = tuple(bowl_x_range)
        self.bowl_y_range = tuple(bowl_y_range)
        self.pre_scoop_offset = np.array(pre_scoop_offset, dtype=float)
        self.post_scoop_offset = np.array(post_scoop_offset, dtype=float)
        self.success_pos_tolerance = success_pos_tolerance
        self.success_tilt_tolerance = np.deg2rad(success_tilt_tolerance_deg)
        self.success_max_speed = success_max_speed
        if not 0 < min_portion_fraction <= 1:
            raise ValueError(f"min_portion_fraction must lie in (0, 1], got {min_portion_fraction!r}")
        self.min_portion_fraction = min_portion_fraction
        self.min_portion_cm3 = min_portion_cm3
        self.max_spill_fraction = max_spill_fraction
        self.fast_rendering = fast_rendering
        self.sleep_tolerance = check_sleep_tolerance(sleep_tolerance)
        self.physics_solver_options = physics_solver_options
        self.physics_timestep_s = check_physics_timestep(physics_timestep_s, control_freq)

        # settings for table top: the bowl sits in the middle of the table
        self.table_full_size = table_full_size
        self.table_offset = np.array((0, 0, 0.8))
        self.bowl_nominal_xy = np.zeros(2)
        if self.humanoid is not None:
            # a humanoid stands at the table's edge and reaches a bowl near it (veragmil_suite.models.humanoid)
            self.bowl_nominal_xy = np.array([-table_full_size[0] / 2 + self.humanoid.bowl_from_table_edge_m, 0.0])

        # reward configuration
        self.reward_scale = reward_scale
        self.reward_shaping = reward_shaping

        # whether to use ground-truth object states
        self.use_object_obs = use_object_obs
        self.use_food_params_obs = use_food_params_obs

        self._metrics_time = None
        self._metrics = None
        self._success_time = None
        self._physics_error = ""

        if controller_configs is None:
            controller_configs = load_scoop_controller_config("OSC_POSE", robot=robot_name)
        elif difference := untuned_controller_difference(controller_configs, robot_name):
            warnings.warn(difference, UntunedControllerWarning, stacklevel=2)

        super().__init__(
            robots=robots,
            env_configuration=env_configuration,
            controller_configs=controller_configs,
            base_types=base_types,
            gripper_types=gripper_types,
            initialization_noise=initialization_noise,
            use_camera_obs=use_camera_obs,
            has_renderer=has_renderer,
            has_offscreen_renderer=has_offscreen_renderer,
            render_camera=render_camera,
            render_collision_mesh=render_collision_mesh,
            render_visual_mesh=render_visual_mesh,
            render_gpu_device_id=render_gpu_device_id,
            control_freq=control_freq,
            lite_physics=lite_physics,
            horizon=horizon,
            ignore_done=ignore_done,
            hard_reset=hard_reset,
            camera_names=camera_names,
            camera_heights=camera_heights,
            camera_widths=camera_widths,
            camera_depths=camera_depths,
            camera_segmentations=camera_segmentations,
            renderer=renderer,
            renderer_config=renderer_config,
            seed=seed,
        )

    # ------------------------------------------------------------------------------------------------------------ #
    # Reward and success                                                                                             #
    # ------------------------------------------------------------------------------------------------------------ #

    def reward(self, action=None):
        """
        Reward function for the task.

        Sparse un-normalized reward:

            - a discrete reward of 1.0 is provided on success

        Un-normalized summed components if using reward shaping (each in [0, 1], weighted to sum to at most 1):

            - Loading: 0.4 x the fraction of the minimum portion in the spoon
            - Carrying: 0.4 x loading x closeness of the spoon to the post-scoop position
            - Leveling: 0.1 x loading x how level the spoon is
            - Clean: 0.1 x (1 - spilled fraction)

        Note that the final reward is scaled by reward_scale.

        Args:
            action (np array): [NOT USED]

        Returns:
            float: reward value
        """
        if self._check_success():
            reward = 1.0
        elif self.reward_shaping:
            m = self._scoop_metrics()
            load = min(1.0, m["spoon_volume_m3"] / self.min_portion_m3)
            dist = np.linalg.norm(m["spoon_pos"] - self._desired_pos())
            reward = 0.4 * load + 0.4 * load * (1 - np.tanh(10.0 * dist))
            reward += 0.1 * load * (1 - min(1.0, m["spoon_tilt"] / (np.pi / 2)))
            reward += 0.1 * (1 - m["spill_fraction"])
            reward = min(reward, 0.99)
        else:
            reward = 0.0
        if self.reward_scale is not None:
            reward *= self.reward_scale
        return reward

    def _check_success(self):
        """
        Success: the spoon is held at the post-scoop pose (within position and tilt tolerances, slower than
        success_max_speed) carrying at least min_portion_cm3 of food, with spilled volume under
        max_spill_fraction of the volume scooped.

        Returns:
            bool: True if the task succeeded
        """
        m = self._scoop_metrics()
        return bool(
            np.linalg.norm(m["spoon_pos"] - self._desired_pos()) <= self.success_pos_tolerance
            and m["spoon_tilt"] <= self.success_tilt_tolerance
            and m["spoon_speed"] <= self.success_max_speed
            and m["spoon_volume_m3"] >= self.min_portion_m3
            and m["spill_fraction"] < self.max_spill_fraction
        )

    # ------------------------------------------------------------------------------------------------------------ #
    # Model                                                                                                          #
    # ------------------------------------------------------------------------------------------------------------ #

    def _load_model(self):
        """
        Loads an xml model, puts it in self.model
        """
        super()._load_model()

        # Adjust base pose accordingly
        robot_model = self.robots[0].robot_model
        xpos = robot_model.base_xpos_offset["table"](self.table_full_size[0])
        if self.humanoid is not None:
            # within the arm's reach of the bowl, on the robot's own floor height
            xpos = (*(self.bowl_nominal_xy + self.humanoid.base_from_bowl_m), xpos[2])
            gripper = self.robots[0].gripper[SPOON_ARM]
            mount = find_elements(robot_model.worldbody, "body", {"name": gripper.root_body}, return_first=True)
            mount.set("quat", array_to_string(self.humanoid.spoon_mount_quat_wxyz))
        robot_model.set_base_xpos(xpos)
        for name in self.robots[0].gripper[SPOON_ARM].important_geoms["spoon"]:
            geom = find_elements(robot_model.worldbody, "geom", {"name": name}, return_first=True)
            for key, value in spoon_contact(self._env_physics).items():
                geom.set(key, value)

        mujoco_arena = ScoopArena(
            table_full_size=self.table_full_size, table_offset=self.table_offset, bowl_xy=self.bowl_nominal_xy
        )
        # Arena always gets set to zero origin
        mujoco_arena.set_origin([0, 0, 0])

        self.bowl = Bowl(name="bowl", shape=self.bowl_shape)
        # One of a few piles per food: each is settled once per machine (veragmil_suite.environments.settling), and the
        # same seed always draws the same one, so the same seed gives the same XML.
        self.food, self.n_grains, self.physics = self._env_food, self._env_n_grains, self._env_physics
        self.grain = self.food.grain(self.physics)
        self.pile_variant = int(self.rng.integers(self.pile_variants))
        self.grain_pile = self._pile(self.pile_variant)

        self.model = ScoopTask(
            mujoco_arena=mujoco_arena,
            mujoco_robots=[robot.robot_model for robot in self.robots],
            mujoco_objects=self.bowl,
            grain_pile=self.grain_pile,
            grain_home_qpos=self.grain_pile.lattice_qpos(self.bowl_shape, self._nominal_rim_center()),
            solver_options=self.solver_options,
            fast_rendering=self.fast_rendering,
            sleep_tolerance=self.sleep_tolerance,
            timestep_s=self.physics_timestep_s,
        )
        if self.humanoid is not None:
            for body1, body2 in self_contact_excludes(robot_model.worldbody):
                self.model.contact.append(new_element("exclude", name=None, body1=body1, body2=body2))

    @property
    def solver_options(self) -> dict:
        """MuJoCo <option> attributes of the scene and of settling: the defaults, updated by physics_solver_options."""
        return {**PHYSICS_SOLVER_OPTIONS[self.physics], **(self.physics_solver_options or {})}

    def _pile(
        self, variant: int, food: FoodSpec | None = None, n_grains: int | None = None, physics: str | None = None
    ) -> GrainPile:
        """Pile variant ``variant`` of this (or the given) food, grain count and physics (the same on every machine)."""
        food = self.food if food is None else food
        n_grains = self.n_grains if n_grains is None else n_grains
        physics = self.physics if physics is None else physics
        rng = np.random.default_rng([variant, n_grains, *map(ord, food.name)])
        return GrainPile(food, n_grains, rng, physics=physics)

    def settled_piles(self) -> dict[str, SettledPile]:
        """
        Every pile variant this environment can draw, settled here (or read from this machine's cache), by cache
        key: what a worker elsewhere is handed (veragmil_suite.environments.settling.use_shipped_piles) to reset this
        environment on the same piles, for any seed.
        """
        timestep = float(self.sim.model.opt.timestep)
        piles = {}
        for variant in range(self.pile_variants):
            pile = self._pile(variant, self._env_food, self._env_n_grains, self._env_physics)
            piles[pile_key(self.bowl, pile, self.solver_options, timestep)] = settle(
                self.bowl, pile, self.solver_options, timestep
            )
        return piles

    def _adopt_loaded_pile(self) -> None:
        """
        Makes food, n_grains, pile_variant and grain_pile those of the pile the simulation was built from.

        reset_from_xml_string (robosuite's playback, robomimic's reset_to, a merged dataset of several foods) may
        load a recorded XML of another food, grain count or pile variant than the one drawn last: the metrics and
        observations must use that pile's grain sizes and volumes. The pile is found among the environment's own
        food's and the catalog's (veragmil_suite.models.foods.FOODS) piles of the grain colour and count loaded.
        """
        model = self.sim.model
        pattern = re.compile(rf"{re.escape(self.grain_pile.name)}(\d+)")
        n_loaded = sum(1 for name in model.body_names if pattern.fullmatch(name))
        body_ids = [model.body_name2id(f"{self.grain_pile.name}{i}") for i in range(n_loaded)]
        first_geoms = model.body_geomadr[body_ids]
        loaded = model.geom_size[first_geoms]
        rgba = model.geom_rgba[first_geoms[0]] if n_loaded else None

        # saved XML keeps 6 significant digits; variants' sizes are drawn from a continuous range
        def holds(pile: GrainPile) -> bool:
            sizes = np.array([np.pad(g[0]["size"], (0, 3 - len(g[0]["size"]))) for g in pile.geoms])
            return np.allclose(sizes, loaded, rtol=1e-5, atol=0)

        if n_loaded == self.grain_pile.n_grains and holds(self.grain_pile):
            return
        foods = []
        for food in (self._env_food, self.food, *FOODS.values()):
            if all(food.name != f.name for f in foods):
                foods.append(food)
        tried = max(self.pile_variants, LOADED_PILE_VARIANTS_TRIED)
        physics_order = [self._env_physics, *(p for p in PHYSICS if p != self._env_physics)]
        for food in foods:
            if n_loaded == 0 or not np.allclose(food.rgba, rgba, atol=1e-5):
                continue
            for physics in physics_order:
                for variant in range(tried):
                    pile = self._pile(variant, food, n_loaded, physics)
                    if holds(pile):
                        self.food, self.n_grains, self.pile_variant, self.grain_pile = food, n_loaded, variant, pile
                        self.physics, self.grain = physics, food.grain(physics)
                        return
        raise ValueError(
            f"the loaded model's {n_loaded} grains are none of the first {tried} piles of {n_loaded} grains of any "
            f"known food ({', '.join(f.name for f in foods)}): register its food "
            "(veragmil_suite.models.foods.register_food) "
            "or make the environment with it"
        )

    def _setup_references(self):
        """
        Sets up references to important components. A reference is typically an
        index or a list of indices that point to the corresponding elements
        in a flatten array, which is how MuJoCo stores physical simulation data.
        """
        super()._setup_references()
        model = self.sim.model
        self.bowl_body_id = model.body_name2id(self.bowl.root_body)
        self.bowl_qpos_adr = model.get_joint_qpos_addr(self.bowl.joints[0])[0]
        self.bowl_qvel_adr = model.get_joint_qvel_addr(self.bowl.joints[0])[0]
        self._adopt_loaded_pile()
        self.grain_body_ids = np.array([model.body_name2id(n) for n in self.grain_pile.body_names])
        self.grain_qpos_adr = np.array([model.get_joint_qpos_addr(n)[0] for n in self.grain_pile.joint_names])
        self.grain_qvel_adr = np.array([model.get_joint_qvel_addr(n)[0] for n in self.grain_pile.joint_names])
        gripper = self.robots[0].gripper[SPOON_ARM]
        self.spoon_site_id = model.site_name2id(gripper.important_sites["spoon_frame"])
        self.spoon_geom_ids = np.array([model.geom_name2id(n) for n in gripper.important_geoms["spoon"]])
        self.grain_geom_ids = np.flatnonzero(np.isin(model.geom_bodyid, self.grain_body_ids))
        self.eef_site_id = self.robots[0].eef_site_id[SPOON_ARM]
        self.grain_volumes_m3 = self.grain_pile.volumes_m3
        self.grain_masses_kg = model.body_mass[self.grain_body_ids].copy()
        if self.min_portion_cm3 is not None:
            self.min_portion_m3 = self.min_portion_cm3 * M3_PER_CM3
        else:
            self.min_portion_m3 = self.min_portion_fraction * float(self.grain_volumes_m3.sum())
        self.grain_radius_max = float(self.grain_pile.radii.max())

    def _reset_internal(self):
        """
        Resets simulation internal configurations: the robot at its pre-scoop pose, the bowl at a random place,
        a settled pile in it.
        """
        self.robots[0].init_qpos = self._pre_scoop_qpos()
        super()._reset_internal()
        use_block_mass_matrix(self.robots[0])
        leave_heading_free(self.robots[0].part_controllers[SPOON_ARM])
        self._metrics_time = None
        self._success_time = None
        self._physics_error = ""
        if self.deterministic_reset:
            return  # a saved state is loaded next (reset_to, reset_from_xml_string): no bowl to place or pile to settle

        # Place the bowl and a settled pile (settled once, then moved rigidly: still settled)
        pile = settle(self.bowl, self.grain_pile, self.solver_options, float(self.sim.model.opt.timestep))
        offset = np.array(
            [
                self.bowl_nominal_xy[0] + self.rng.uniform(*self.bowl_x_range),
                self.bowl_nominal_xy[1] + self.rng.uniform(*self.bowl_y_range),
                self.table_offset[2],
            ]
        )
        yaw = self.rng.uniform(-np.pi, np.pi)
        turn = T.axisangle2quat(np.array([0.0, 0.0, yaw]))  # (x, y, z, w)
        rot = T.quat2mat(turn)
        qpos = self.sim.data.qpos
        bowl_q = pile.bowl_qpos.copy()
        bowl_q[:3] = rot @ bowl_q[:3] + offset
        qpos[self.bowl_qpos_adr : self.bowl_qpos_adr + 7] = bowl_q
        grains = pile.grain_qpos
        idx = self.grain_qpos_adr[:, None] + np.arange(7)
        new = np.empty_like(grains)
        new[:, :3] = grains[:, :3] @ rot.T + offset
        turn_wxyz = T.convert_quat(turn, to="wxyz")
        new[:, 3:] = _quat_mul_wxyz(turn_wxyz, grains[:, 3:])
        qpos[idx] = new
        self.sim.data.qvel[self.grain_qvel_adr[:, None] + np.arange(6)] = 0.0
        self.sim.data.qvel[self.bowl_qvel_adr : self.bowl_qvel_adr + 6] = 0.0
        self.sim.forward()
        self.settled_max_speed = pile.max_speed_m_s

    def _pre_scoop_qpos(self) -> np.ndarray:
        """
        Joint configuration (of all the robot's joints) that puts the spoon at its pre-scoop pose above the nominal
        bowl (cached). A humanoid solves for its spoon arm alone, with the heading free (its arm has five joints),
        and its other parts take the pose their controllers hold.
        """
        robot = self.robots[0]
        model = robot.robot_model
        # everything the pose depends on: the arm, what it holds, and where the bowl's rim is
        key = (
            type(model).__name__,
            type(robot.gripper[SPOON_ARM]).__name__,
            repr(self.bowl_shape),
            tuple(self.pre_scoop_offset),
            tuple(self.table_full_size),
            tuple(np.round(self.table_offset, 9)),
            tuple(np.round(self.bowl_nominal_xy, 9)),
        )
        if key not in _PRE_SCOOP_CACHE:
            target_pos = self._nominal_rim_center() + self.pre_scoop_offset
            site = robot.gripper[SPOON_ARM].important_sites["grip_site"]
            if self.humanoid is None:
                _PRE_SCOOP_CACHE[key] = solve_pose_ik(
                    self.sim.model._model,
                    joint_names=model.joints,
                    site_name=site,
                    target_pos=target_pos,
                    target_rot=PRE_SCOOP_EEF_ROT,
                    q_init=np.array(model.init_qpos, dtype=float),
                )
            else:
                held = self._held_joint_qpos()
                arm = self._spoon_arm_joints()
                q_arm = solve_pose_ik(
                    self.sim.model._model,
                    joint_names=arm,
                    site_name=site,
                    target_pos=target_pos,
                    target_rot=PRE_SCOOP_EEF_ROT,
                    q_init=np.array(self.humanoid.arm_ik_start, dtype=float),
                    free_heading=True,
                    other_qpos=held,
                )
                held.update(zip(arm, q_arm))
                _PRE_SCOOP_CACHE[key] = np.array([held[name] for name in model.joints])
        return _PRE_SCOOP_CACHE[key].copy()

    def _spoon_arm_joints(self) -> list[str]:
        """The spoon arm's joint names (robosuite lists the right arm's first and splits the arm joints evenly)."""
        robot = self.robots[0]
        joints = robot.robot_model.arm_joints
        return list(joints[: len(joints) // len(robot.arms)])

    def _held_joint_qpos(self) -> dict[str, float]:
        """A humanoid's held joint positions by joint name: the other arm's and the torso's (the layout's)."""
        model = self.robots[0].robot_model
        spoon_arm = self._spoon_arm_joints()
        joints = {"left": list(model.arm_joints[len(spoon_arm) :]), "torso": list(model.torso_joints)}
        return {
            name: float(value)
            for part, values in self.humanoid.held_qpos.items()
            for name, value in zip(joints[part], values, strict=True)
        }

    def _nominal_rim_center(self) -> np.ndarray:
        return np.array(
            [self.bowl_nominal_xy[0], self.bowl_nominal_xy[1], self.table_offset[2] + self.bowl_shape.height]
        )

    # ------------------------------------------------------------------------------------------------------------ #
    # Task state                                                                                                     #
    # ------------------------------------------------------------------------------------------------------------ #

    def _rim_center(self) -> np.ndarray:
        """Centre of the bowl's rim in the world (the bowl may be nudged)."""
        pos = self.sim.data.body_xpos[self.bowl_body_id]
        mat = self.sim.data.body_xmat[self.bowl_body_id].reshape(3, 3)
        return pos + mat @ self.bowl.rim_offset

    def _desired_pos(self) -> np.ndarray:
        """Post-scoop position of the spoon: a fixed offset from the bowl's rim (a function of the state alone)."""
        return self._rim_center() + self.post_scoop_offset

    def _scoop_metrics(self) -> dict:
        """Where every grain is (bowl, spoon, spilled), computed once per simulation time."""
        data = self.sim.data
        stamp = (data.time, hash(data.qpos.tobytes()))  # hand-set states (tests, reset_to) change qpos, not time
        if self._metrics_time == stamp and self._metrics is not None:
            return self._metrics
        pos = data.body_xpos[self.grain_body_ids]
        rim = self._rim_center()
        bowl_axis = data.body_xmat[self.bowl_body_id].reshape(3, 3)[:, 2]
        rel = pos - rim
        radial = rel - np.outer(rel @ bowl_axis, bowl_axis)
        in_bowl = np.linalg.norm(radial, axis=1) <= min(self.bowl_shape.rim_semi_axes)

        spoon_pos = data.site_xpos[self.spoon_site_id]
        spoon_rot = data.site_xmat[self.spoon_site_id].reshape(3, 3)
        local = (pos - spoon_pos) @ spoon_rot
        a, b = SPOON_SHAPE.rim_semi_axes
        margin = self.grain_radius_max
        in_spoon = (
            ((local[:, 0] / (a + margin)) ** 2 + (local[:, 1] / (b + margin)) ** 2 <= 1.0)
            & (local[:, 2] >= -SPOON_SHAPE.depth - margin)
            & (local[:, 2] <= 3 * margin)
        )
        spilled = ~in_bowl & ~in_spoon
        vol = self.grain_volumes_m3
        spoon_volume = float(vol[in_spoon].sum())
        spilled_volume = float(vol[spilled].sum())
        mass = self.grain_masses_kg
        lifted = float(vol[~in_bowl].sum()) + float(vol[in_spoon & in_bowl].sum())
        spoon_vel = np.zeros(6)
        mujoco.mj_objectVelocity(
            self.sim.model._model, data._data, mujoco.mjtObj.mjOBJ_SITE, self.spoon_site_id, spoon_vel, 0
        )
        self._metrics = dict(
            in_bowl=in_bowl,
            in_spoon=in_spoon,
            spilled=spilled,
            grains_in_spoon=int(in_spoon.sum()),
            grains_spilled=int(spilled.sum()),
            spoon_volume_m3=spoon_volume,
            spilled_volume_m3=spilled_volume,
            spoon_mass_kg=float(mass[in_spoon].sum()),
            spilled_mass_kg=float(mass[spilled].sum()),
            lifted_volume_m3=lifted,
            spill_fraction=spilled_volume / lifted if lifted > 0 else 0.0,
            spoon_pos=spoon_pos.copy(),
            spoon_tilt=float(np.arccos(np.clip(spoon_rot[2, 2], -1.0, 1.0))),
            spoon_speed=float(np.linalg.norm(spoon_vel[3:])),
        )
        self._metrics_time = stamp
        return self._metrics

    def step(self, action):
        """
        robosuite's step, except that an action with NaN or inf is not executed: it ends the episode with
        info["physics_error"] naming it, as a physics blow-up does (OSC turned it into a limp, falling arm).
        """
        values = np.asarray(action, dtype=float)
        if np.isfinite(values).all() or self.done:
            return super().step(action)
        bad = np.flatnonzero(~np.isfinite(values)).tolist()
        self._physics_error = f"non-finite action (NaN or inf at indices {bad}); actions must be finite numbers"
        self.done = True
        return self._get_observations(), 0.0, True, self.scoop_info()

    def _physics_check(self) -> str:
        """A description of a physics blow-up, or "" when the simulation is sound."""
        data = self.sim.data
        if _instability_warnings(data) > self._badqacc_seen:
            return "MuJoCo reported unstable positions, velocities or accelerations and reset the simulation"
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            return "non-finite positions or velocities"
        pos = data.body_xpos[self.grain_body_ids]
        far = np.linalg.norm(pos[:, :2] - self.table_offset[:2], axis=1) > 2.0
        if far.any() or (pos[:, 2] < -0.1).any():
            return f"{int(far.sum() + (pos[:, 2] < -0.1).sum())} grains left the workspace"
        return ""

    def _post_action(self, action):
        """
        Adds the task's metrics to info, and ends the episode on a physics blow-up.

        Returns:
            3-tuple:
                - (float) reward from the environment
                - (bool) whether the current episode is completed or not
                - (dict) info about the step
        """
        self._update_kinematics()
        self._physics_error = self._physics_error or self._physics_check()
        if self._physics_error:
            reward, done, info = 0.0, True, {}
        else:
            reward, done, info = super()._post_action(action)
        info.update(self.scoop_info())
        return reward, done, info

    def _update_kinematics(self) -> None:
        """
        Brings positions, velocities and cameras up to the state reached; changes nothing in the trajectory.

        Lite physics leaves them a substep behind (mj_step2 integrates after they were computed). Observations,
        metrics and rendering read only these, so this skips a full forward's collision and constraint stages:
        0.03 ms against 2.6 ms with the rice pile's contacts (5% of a step).
        """
        model, data = self.sim.model._model, self.sim.data._data
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_camlight(model, data)
        mujoco.mj_comVel(model, data)

    def _update_observables(self, force=False):
        """
        Samples observables once per control step, at its end (see _get_observations).

        robosuite samples them inside the substep loop, where float time sums (12 x 1/240 s falls just short of
        1/20 s) move the sample to the second substep of the period: step() would return an observation almost a
        control step old, and cameras would render twice per step.
        """
        if force:
            super()._update_observables(force=True)

    def _get_observations(self, force_update=False):
        """Observations of the state reached, so an observation is a function of the recorded state."""
        return super()._get_observations(force_update=True)

    def scoop_info(self) -> dict:
        """The task's metrics now: grains in the spoon and spilled, spilled volume, completion time, success."""
        elapsed = self.timestep * self.control_timestep
        if self._physics_error:
            return dict(
                grains_in_spoon=0,
                grains_spilled=0,
                spilled_volume_cm3=0.0,
                spill_fraction=0.0,
                scooped_volume_cm3=0.0,
                spoon_mass_g=0.0,
                spilled_mass_g=0.0,
                completion_time_s=elapsed,
                success=False,
                stage=SCOOP_STAGES[0],
                physics_error=self._physics_error,
            )
        m = self._scoop_metrics()
        success = self._check_success()
        if success and self._success_time is None:
            self._success_time = elapsed
        return dict(
            grains_in_spoon=m["grains_in_spoon"],
            grains_spilled=m["grains_spilled"],
            spilled_volume_cm3=m["spilled_volume_m3"] / M3_PER_CM3,
            spill_fraction=m["spill_fraction"],
            scooped_volume_cm3=m["lifted_volume_m3"] / M3_PER_CM3,
            spoon_volume_cm3=m["spoon_volume_m3"] / M3_PER_CM3,
            spoon_mass_g=1000.0 * m["spoon_mass_kg"],
            spilled_mass_g=1000.0 * m["spilled_mass_kg"],
            completion_time_s=self._success_time if self._success_time is not None else elapsed,
            success=success,
            stage=self.scoop_stage(),
            physics_error="",
        )

    def scoop_stage(self) -> str:
        """
        The furthest stage of SCOOP_STAGES this state shows, short of "held" (success held over time, which the
        episode loop decides): the spoon at the post-scoop pose (position and tilt within the success
        tolerances) carrying the minimum portion; that portion lifted clear of the rim (every grain in the
        spoon above the rim by a grain's radius); the minimum portion in the spoon; the spoon touching a grain.
        """
        m = self._scoop_metrics()
        loaded = m["spoon_volume_m3"] >= self.min_portion_m3
        if loaded:
            at_pose = (
                np.linalg.norm(m["spoon_pos"] - self._desired_pos()) <= self.success_pos_tolerance
                and m["spoon_tilt"] <= self.success_tilt_tolerance
            )
            if at_pose:
                return SCOOP_STAGES[4]
            data = self.sim.data
            bowl_axis = data.body_xmat[self.bowl_body_id].reshape(3, 3)[:, 2]
            heights = (data.body_xpos[self.grain_body_ids[m["in_spoon"]]] - self._rim_center()) @ bowl_axis
            return SCOOP_STAGES[3] if heights.min() > self.grain_radius_max else SCOOP_STAGES[2]
        return SCOOP_STAGES[1] if self._spoon_touches_grain() else SCOOP_STAGES[0]

    def _spoon_touches_grain(self) -> bool:
        """Whether a contact of the last collision pass joins a spoon geom and a grain."""
        data = self.sim.data._data
        if data.ncon == 0:
            return False
        geoms = data.contact.geom[: data.ncon]
        spoon = np.isin(geoms, self.spoon_geom_ids)
        grain = np.isin(geoms, self.grain_geom_ids)
        return bool(((spoon[:, 0] & grain[:, 1]) | (spoon[:, 1] & grain[:, 0])).any())

    # ------------------------------------------------------------------------------------------------------------ #
    # Observations                                                                                                   #
    # ------------------------------------------------------------------------------------------------------------ #

    def _setup_observables(self):
        """
        Sets up observables to be used for this environment. Creates object-based observables if enabled

        Returns:
            OrderedDict: Dictionary mapping observable names to its corresponding Observable object
        """
        observables = super()._setup_observables()

        robot = self.robots[0]
        if len(robot.arms) > 1:
            # a two-armed robot's spoon arm under the single-arm names, so the expert, policies and robomimic
            # configs read the spoon's pose under the same keys on every robot (robosuite adds right_/left_)
            pf = robot.robot_model.naming_prefix
            for name in ("eef_pos", "eef_quat", "eef_quat_site"):
                source = observables[f"{pf}{SPOON_ARM}_{name}"]
                observables[f"{pf}{name}"] = Observable(
                    name=f"{pf}{name}", sensor=source._sensor, sampling_rate=self.control_freq
                )

        if self.use_object_obs:
            modality = "object"

            @sensor(modality=modality)
            def desired_pose(obs_cache):
                pos = self._desired_pos()
                return np.concatenate([pos, T.mat2quat(POST_SCOOP_EEF_ROT)])

            @sensor(modality=modality)
            def bowl_pos(obs_cache):
                return self._rim_center()

            @sensor(modality=modality)
            def spoon_to_desired_pos(obs_cache):
                return self._desired_pos() - self.sim.data.site_xpos[self.eef_site_id]

            @sensor(modality=modality)
            def spoon_load(obs_cache):
                # grains in the spoon, grains spilled (a vector: robosuite squeezes one-element observations)
                m = self._scoop_metrics()
                return np.array([m["grains_in_spoon"], m["grains_spilled"]], dtype=float)

            sensors = [desired_pose, bowl_pos, spoon_to_desired_pos, spoon_load]

            if self.use_food_params_obs:

                @sensor(modality=modality)
                def food_params(obs_cache):
                    g = self.grain
                    return np.array([g.mean_size_m, g.friction, g.restitution, g.density_kg_m3 / 1000.0])

                sensors.append(food_params)

            for s in sensors:
                observables[s.__name__] = Observable(name=s.__name__, sensor=s, sampling_rate=self.control_freq)

        return observables

    def initialize_time(self, control_freq):
        """
        Initializes the time constants used for simulation: the task's own physics step (physics_timestep_s, see
        ScoopTask), which must divide the control period; a model loaded from XML brings its own (_initialize_sim).
        """
        super().initialize_time(control_freq)
        self.model_timestep = self.physics_timestep_s  # checked against control_freq in __init__

    def _initialize_sim(self, xml_string=None):
        super()._initialize_sim(xml_string)
        self._badqacc_seen = 0
        # a recorded XML runs at the step it was recorded with (datasets keep their own physics), exactly: a saved
        # XML's rounded step is the whole fraction of the control period it was (check_physics_timestep)
        self.model_timestep = check_physics_timestep(float(self.sim.model.opt.timestep), self.control_freq)
        self.sim.model.opt.timestep = self.model_timestep
        keep_sim_xml(
            self.sim, functools.partial(self._compiled_xml, xml_string, self.model, list(self._xml_processors))
        )

    @staticmethod
    def _compiled_xml(xml_string, model, processors) -> str:
        """The XML MujocoEnv._initialize_sim compiled: ``xml_string`` or the model's, through the XML processors."""
        xml = xml_string if xml_string else model.get_xml()
        for processor in processors:
            xml = processor(xml)
        return xml

    def reset(self, seed: int | None = None):
        """
        robosuite's reset; with ``seed`` the env's generator is seeded first, so the episode (pile variant, bowl
        place and turn, initialization noise) depends on that seed alone, whatever episodes came before.
        """
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        obs = super().reset()
        self._badqacc_seen = _instability_warnings(self.sim.data)
        return obs


class StageTracker:
    """The furthest of SCOOP_STAGES an episode reached, from each step's info; "held" when its last step succeeds
    (the episode's success, as its metrics count it)."""

    def __init__(self):
        self.index = 0
        self.success = False

    def update(self, info: dict) -> None:
        stage = info.get("stage")
        if stage in SCOOP_STAGES:
            self.index = max(self.index, SCOOP_STAGES.index(stage))
        self.success = bool(info.get("success", False))

    @property
    def stage(self) -> str:
        return SCOOP_STAGES[-1] if self.success else SCOOP_STAGES[self.index]


_PRE_SCOOP_CACHE: dict[tuple, np.ndarray] = {}
_INSTABILITY_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)


def _instability_warnings(data) -> int:
    """How many times MuJoCo found non-finite or huge state and reset itself (it does so silently)."""
    return sum(data.warning[w].number for w in _INSTABILITY_WARNINGS)


def _quat_mul_wxyz(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """q * p for one (w, x, y, z) quaternion q and an (n, 4) array p."""
    w0, x0, y0, z0 = q
    w1, x1, y1, z1 = p.T
    return np.stack(
        [
            w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
            w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
            w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
            w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
        ],
        axis=1,
    )
