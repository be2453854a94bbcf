"""ScoopGranular: scoop granular food from a bowl with a spoon and carry it to a post-scoop pose without spilling."""

from __future__ import annotations

import contextlib
import functools
import warnings
from collections.abc import Iterator

import mujoco
import numpy as np
import robosuite.utils.transform_utils as T
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv
from robosuite.utils.mjcf_utils import array_to_string, find_elements, new_element

from veragmil_suite.controllers.fast_control import use_block_mass_matrix
from veragmil_suite.controllers.scoop_config import (
    UntunedControllerWarning,
    leave_heading_free,
    load_scoop_controller_config,
    untuned_controller_difference,
)
from veragmil_suite.environments.arguments import check_arguments, check_grain_count
from veragmil_suite.environments.pile_variants import PileVariantsMixin
from veragmil_suite.environments.render_context import RenderContextMixin
from veragmil_suite.environments.settling import settle
from veragmil_suite.environments.start_pose import StartPoseMixin
from veragmil_suite.environments.task_state import (
    DEFAULT_SPILL_LIMIT,
    M3_PER_CM3,
    TaskStateMixin,
    check_spill_limit,
    instability_warnings,
)
from veragmil_suite.models.arena import ScoopArena
from veragmil_suite.models.bowl import DEFAULT_BOWL_SHAPE, Bowl
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import DEFAULT_PHYSICS, FoodSpec, GrainModel, check_physics, get_food
from veragmil_suite.models.humanoid import (
    SPOON_ARM,
    HumanoidLayout,
    check_robot,
    humanoid_layout,
    self_contact_excludes,
)
from veragmil_suite.models.scoop_task import (
    GRAIN_SLEEP_TOLERANCE,
    PHYSICS_TIMESTEP_S,
    ScoopTask,
    check_physics_timestep,
    check_sleep_tolerance,
    pile_solver_options,
)
from veragmil_suite.models.spoon_gripper import spoon_contact
from veragmil_suite.utils.kinematics import quat_mul_wxyz
from veragmil_suite.utils.sim_xml import keep_sim_xml


class ScoopGranular(TaskStateMixin, StartPoseMixin, PileVariantsMixin, RenderContextMixin, ManipulationEnv):
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
        spill_limit_of (str): what max_spill_fraction is a fraction of: "scooped" (the volume lifted out of the
            bowl) or "bowl" (all the food in the bowl)
        table_full_size (3-tuple): x, y, and z dimensions of the table
        use_camera_obs (bool): if True, every observation includes rendered image(s)
        use_object_obs (bool): if True, include task information (desired pose, bowl, spoon load) in the
            observation
        use_food_params_obs (bool): if True, add the food's physical parameters to the object observations
            (off by default so results on unseen foods stay honest)
        use_wrench_obs (bool): if True, add the wrist force-torque sensor (robot0_eef_force, robot0_eef_torque). It
            reads the torques applied in a step, not the state alone, so robomimic's dataset_states_to_obs cannot
            regenerate it: off by default, so a dataset's every observation can be extracted from its states
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
        spill_limit_of=DEFAULT_SPILL_LIMIT,
        table_full_size=(0.8, 0.8, 0.05),
        use_camera_obs=True,
        use_object_obs=True,
        use_food_params_obs=False,
        use_wrench_obs=False,
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
        check_arguments({name: value for name, value in locals().items() if name not in ("self", "__class__")})
        self.food: FoodSpec = get_food(food)
        self.physics = check_physics(physics)
        self.grain: GrainModel = self.food.grain(self.physics)
        robot_name = robots if isinstance(robots, str) else robots[0]
        check_robot(robot_name)
        self.humanoid: HumanoidLayout | None = humanoid_layout(robot_name)
        if self.humanoid is not None and isinstance(gripper_types, str):
            gripper_types = [[gripper_types, None]]  # per arm (right, left) of the one robot
        self.n_grains = check_grain_count(n_grains, self.food, self.physics)
        # food, physics and n_grains are the simulation's (a loaded model's may differ); these are what fresh
        # models get
        self._env_food, self._env_physics, self._env_n_grains = self.food, self.physics, self.n_grains
        self.pile_variants = int(pile_variants)
        for label, rng_range, half in (
            ("bowl_x_range", bowl_x_range, table_full_size[0] / 2),
            ("bowl_y_range", bowl_y_range, table_full_size[1] / 2),
        ):
            if not -half <= rng_range[0] <= rng_range[1] <= half:
                raise ValueError(f"{label} must lie on the table, within +-{half:g} m of its centre, got {rng_range!r}")
        self.bowl_shape = bowl_shape
        self.bowl_x_range = tuple(bowl_x_range)
        self.bowl_y_range = tuple(bowl_y_range)
        self.pre_scoop_offset = np.array(pre_scoop_offset, dtype=float)
        self.post_scoop_offset = np.array(post_scoop_offset, dtype=float)
        self.success_pos_tolerance = success_pos_tolerance
        self.success_tilt_tolerance = np.deg2rad(success_tilt_tolerance_deg)
        self.success_max_speed = success_max_speed
        self.min_portion_fraction = min_portion_fraction
        self.min_portion_cm3 = min_portion_cm3
        self.max_spill_fraction = max_spill_fraction
        self.spill_limit_of = check_spill_limit(spill_limit_of)
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
        self.use_wrench_obs = use_wrench_obs

        self._metrics_time = None
        self._metrics = None
        self._success_time = None
        self._physics_error = ""
        self._restored_start = False  # the next step follows a deterministic reset: it holds the restored pose

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
        # robosuite would refuse an unknown camera only at its observables, naming the observable, not the camera
        cameras = [camera.get("name") for camera in self.model.worldbody.iter("camera")]
        unknown = [name for name in self.camera_names if name not in cameras]
        if unknown:
            raise ValueError(
                f"no camera {', '.join(map(repr, unknown))} in this scene; its cameras: {', '.join(cameras)}"
            )

    @property
    def solver_options(self) -> dict:
        """MuJoCo <option> attributes of the scene and of settling: its food's and physics' (pile_solver_options),
        updated by physics_solver_options."""
        grain = self._env_food.grain(self._env_physics)
        return {**pile_solver_options(grain, self._env_physics), **(self.physics_solver_options or {})}

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
        self.food_volume_m3 = float(self.grain_volumes_m3.sum())  # all the food in the bowl
        self.grain_masses_kg = model.body_mass[self.grain_body_ids].copy()
        if self.min_portion_cm3 is not None:
            self.min_portion_m3 = self.min_portion_cm3 * M3_PER_CM3
        else:
            self.min_portion_m3 = self.min_portion_fraction * self.food_volume_m3
        self.grain_radius_max = float(self.grain_pile.radii.max())
        # the largest piece's length and thickness (m): what a camera over the bowl sees of the food
        self.piece_size_m = 2.0 * np.array([self.grain_radius_max, self.grain_pile.thickness_radii.max()])

    def _reset_internal(self):
        """
        Resets simulation internal configurations: the robot at its pre-scoop pose, the bowl at a random place,
        a settled pile in it.
        """
        self.robots[0].init_qpos = self._pre_scoop_qpos()
        super()._reset_internal()
        self._remember_render_context()
        use_block_mass_matrix(self.robots[0])
        leave_heading_free(self.robots[0].part_controllers[SPOON_ARM])
        self._metrics_time = None
        self._success_time = None
        self._physics_error = ""
        # a saved state is loaded next (reset_to, reset_from_xml_string): no bowl to place or pile to settle, and the
        # first step holds the pose of that state (hold_restored_pose)
        self._restored_start = self.deterministic_reset
        self.pile_key = ""  # the settled pile's cache key, which episode records name; "" for a restored state
        if self.deterministic_reset:
            return

        # Place the bowl and a settled pile (settled once, then moved rigidly: still settled)
        pile = settle(self.bowl, self.grain_pile, self.solver_options, float(self.sim.model.opt.timestep))
        self.pile_key = pile.key
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
        new[:, 3:] = quat_mul_wxyz(turn_wxyz, grains[:, 3:])
        qpos[idx] = new
        self.sim.data.qvel[self.grain_qvel_adr[:, None] + np.arange(6)] = 0.0
        self.sim.data.qvel[self.bowl_qvel_adr : self.bowl_qvel_adr + 6] = 0.0
        self.sim.forward()
        self.settled_max_speed = pile.max_speed_m_s

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, dict]:
        """
        robosuite's step, except that an action with NaN or inf is not executed: it ends the episode with
        info["physics_error"] naming it, as a physics blow-up does (OSC turned it into a limp, falling arm).
        """
        values = np.asarray(action)
        if values.dtype.kind not in "iuf" or values.shape != (self.action_dim,):
            raise ValueError(
                f"an action must be {self.action_dim} real numbers (env.action_spec), got {values.dtype} values of "
                f"shape {values.shape}"
            )
        if self._restored_start:
            self.hold_restored_pose()
        if np.isfinite(values).all() or self.done:
            return super().step(action)
        bad = np.flatnonzero(~np.isfinite(values)).tolist()
        self._physics_error = f"non-finite action (NaN or inf at indices {bad}); actions must be finite numbers"
        self.done = True
        return self._get_observations(), 0.0, True, self.scoop_info()

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

    def initialize_time(self, control_freq: float) -> None:
        """
        Initializes the time constants used for simulation: the task's own physics step (physics_timestep_s, see
        ScoopTask), which must divide the control period; a model loaded from XML brings its own (_initialize_sim).
        """
        super().initialize_time(control_freq)
        self.model_timestep = self.physics_timestep_s  # checked against control_freq in __init__

    def _initialize_sim(self, xml_string=None):
        super()._initialize_sim(xml_string)
        self._keep_render_context()
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

    def reset(self, seed: int | None = None) -> dict:
        """
        robosuite's reset; with ``seed`` the env's generator is seeded first, so the episode (pile variant, bowl
        place and turn, initialization noise) depends on that seed alone, whatever episodes came before.
        """
        if seed is not None:
            check_arguments({"seed": seed})
            self.rng = np.random.default_rng(seed)
        obs = super().reset()
        self._badqacc_seen = instability_warnings(self.sim.data)
        return obs

    def hold_restored_pose(self, episode_start: bool = True) -> None:
        """
        Aims the robots' controllers at the pose of the state just set, as a reset aims them at the pose it drew.

        A state is restored (robomimic's ``reset_to``, robosuite's playback, a recording's restart) by a deterministic
        reset, which loads the controllers at the noise-free start pose, and then ``sim.set_state``: without this the
        controllers keep that pose as their reference, and the first step pulls the arm up to 3 cm and 4 degrees from
        the restored pose toward it (results/start_mismatch/), so a recorded or replayed episode would not start where
        it was set. The first step after a deterministic reset calls it, whichever tool set the state.

        Args:
            episode_start (bool): the state starts an episode, and the arm's posture (OSC's nullspace target) is its
                joints; False: a state within an episode, whose controllers keep the posture of its start
        """
        self._restored_start = False
        self.sim.forward()
        for robot in self.robots:
            controller = robot.composite_controller
            for part in controller.part_controllers.values():
                if episode_start:
                    part.update_initial_joints(self.sim.data.qpos[part.qpos_index])
                else:
                    part.update(force=True)
            controller.update_state()
            controller.reset()


# what headless() sets whatever the kwargs: environments that differ only here draw the same piles
HEADLESS = dict(seed=0, has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)


@contextlib.contextmanager
def headless(env_kwargs: dict) -> Iterator[ScoopGranular]:
    """
    A ScoopGranular of these kwargs (seed 0, no renderer, no cameras), closed after: the same piles to draw and the
    same low-dim observations as any environment of these kwargs, for checking what stored episodes and demos name.
    """
    import robosuite  # the registry of this process, ScoopGranular's included

    env = robosuite.make("ScoopGranular", **{**env_kwargs, **HEADLESS})
    try:
        yield env
    finally:
        env.close()
