"""
ScoopGranular as a Gymnasium environment: reinforcement-learning libraries and LeRobot reach a simulator through
``gymnasium.make``, not robosuite's API.

    import gymnasium, veragmil_suite        # importing the package registers the id
    env = gymnasium.make("veragmil/ScoopGranular-v0", food="rice")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

Built on robosuite's GymWrapper. An episode ends by the rule the suite's recorded and scored episodes end by
(veragmil_suite.environments.episode): ``terminated`` once success has held SUCCESS_HOLD_S (``info["is_success"]``) or
at a physics error (``info["physics_error"]`` names it), ``truncated`` at the env's horizon. The robosuite env stays
reachable (``env.unwrapped.robosuite_env``), so the suite's own tools (EpisodeRecorder, the scripted expert) work on
Gymnasium-driven episodes as they are.
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import robosuite
import robosuite.macros
from gymnasium import spaces
from robosuite.wrappers.gym_wrapper import GymWrapper

from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.data.recording import EpisodeRecorder
from veragmil_suite.environments.arguments import check_arguments
from veragmil_suite.environments.episode import SUCCESS_HOLD_S, SuccessHold
from veragmil_suite.environments.scoop import ScoopGranular
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.models.foods import FoodSpec
from veragmil_suite.utils.numbers import is_whole

GYM_ENV_ID = "veragmil/ScoopGranular-v0"
# "state": one flat float64 vector (object-state, then each robot's proprio-state, robosuite's GymWrapper keys);
# "pixels": a dict of that vector under "state" and every camera's images, upright (as datasets store them)
OBS_MODES = ("state", "pixels")
RENDER_MODES = ("rgb_array",)


class ScoopGranularGymEnv(GymWrapper):
    """
    ScoopGranular behind Gymnasium's API (reset(seed, options) -> (obs, info); step -> (obs, reward, terminated,
    truncated, info)).

    Args:
        food (str or FoodSpec): a catalog food name (veragmil_suite.models.foods.FOODS) or a custom FoodSpec
        robots (str): the robot arm
        obs_mode (str): "state" (a flat low-dimensional Box) or "pixels" (a Dict of that vector under "state" and
            the images of ``camera_names``: ``<camera>_image`` uint8 (H, W, 3), ``<camera>_depth`` with
            camera_depths=True)
        render_mode (None or str): "rgb_array": render() returns a frame of ``render_camera`` (robosuite's kwarg,
            "agentview" by default) of ``render_size`` (height, width)
        render_size (2-tuple): height and width of render() frames
        success_hold_s (None or float): seconds success must hold to terminate the episode (the suite's rule);
            None or <= 0: success never terminates it (``is_success`` is then the step's own success)
        record (bool): step through an EpisodeRecorder (``recorder``), so an episode can be written with
            veragmil_suite.data.writer.DemoWriter (``env_kwargs`` gives its env metadata); an action outside the
            action space is then clipped to it before it is executed (as the controller would clip it) and stored
            clipped: the file holds what the robot applied
        **env_kwargs: ScoopGranular's other arguments (n_grains, horizon, control_freq, camera_names, camera_heights,
            camera_widths, camera_depths, reward_shaping, seed, ...); not use_camera_obs, which obs_mode sets

    Raises:
        ValueError: [Unknown obs_mode or render_mode, use_camera_obs given, anything ScoopGranular refuses]
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 20}

    def __init__(
        self,
        food: str | FoodSpec = "rice",
        robots: str = "XArm7",
        obs_mode: str = "state",
        render_mode: str | None = None,
        render_size: tuple[int, int] = (256, 256),
        success_hold_s: float | None = SUCCESS_HOLD_S,
        record: bool = False,
        **env_kwargs,
    ):
        if obs_mode not in OBS_MODES:
            raise ValueError(f"Unknown obs_mode {obs_mode!r}; accepted obs modes: {', '.join(OBS_MODES)}")
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(
                f"Unknown render_mode {render_mode!r}; accepted render modes: None, {', '.join(RENDER_MODES)}"
            )
        if "use_camera_obs" in env_kwargs:
            raise ValueError("use_camera_obs is set by obs_mode: obs_mode='pixels' adds camera images")
        check_arguments({"robots": robots})  # the rest are ScoopGranular's to check, at make
        sizes = list(render_size) if isinstance(render_size, (tuple, list)) else []
        if len(sizes) != 2 or not all(is_whole(size) and size > 0 for size in sizes):
            raise ValueError(f"render_size must be (height, width), two positive integers, got {render_size!r}")
        pixels = obs_mode == "pixels"
        kwargs = dict(
            robots=robots,
            food=food,
            has_renderer=False,
            has_offscreen_renderer=pixels or render_mode is not None,
            use_camera_obs=pixels,
        )
        kwargs.update(env_kwargs)
        if kwargs.get("controller_configs") is None:
            # the env's own default, spelled out: datasets store the controller they were driven with
            robot = robots if isinstance(robots, str) else robots[0]
            kwargs["controller_configs"] = load_scoop_controller_config("OSC_POSE", robot=robot)
        # the robosuite.make arguments (JSON-serializable with a catalog food): schema.env_meta's input
        self.env_kwargs = kwargs
        env = robosuite.make(ScoopGranular.__name__, **kwargs)
        keys = (["object-state"] if env.use_object_obs else []) + [
            f"robot{i}_proprio-state" for i in range(len(env.robots))
        ]
        with warnings.catch_warnings():
            # its action Box casts robosuite's float64 bounds (-1, 1) to float32, exactly: the warning says nothing
            warnings.filterwarnings("ignore", message=".*precision lowered by casting to float32")
            super().__init__(env, keys=keys, flatten_obs=not pixels)
        self.obs_mode = obs_mode
        self.render_mode = render_mode
        self.render_size = tuple(render_size)
        self.metadata = {**self.metadata, "render_fps": env.control_freq}
        self.hold = SuccessHold(env.control_freq, success_hold_s)
        self.recorder = None
        if record:
            self.recorder = EpisodeRecorder(env)
        self.robosuite_obs = self.env.observation_spec()

        # float64 as robosuite computes it (and datasets store it), no bounds; images with their own dtype
        state = spaces.Box(-np.inf, np.inf, shape=self._state(self.robosuite_obs).shape, dtype=np.float64)
        if pixels:
            images = self._images(self.robosuite_obs)
            self.observation_space = spaces.Dict({"state": state, **{k: _image_space(v) for k, v in images.items()}})
        else:
            self.observation_space = state

    @property
    def unwrapped(self) -> ScoopGranularGymEnv:
        """This env (Gymnasium's meaning; robosuite's Wrapper would give the robosuite env: ``robosuite_env``)."""
        return self

    @property
    def robosuite_env(self) -> ScoopGranular:
        """The ScoopGranular env underneath: robosuite's API (sim, scoop_info, reset_to...) and the suite's tools."""
        return self.env

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray | dict, dict]:
        """
        Starts an episode. With ``seed``, ScoopGranular's own generator is seeded (its reset(seed)): the bowl, the
        pile and the first observation depend on that seed alone, as in veragmil-collect's attempt of that seed.
        ``options`` are accepted (Gymnasium's signature) and unused.

        Returns:
            2-tuple: the observation, and info (the task's metrics, ``is_success`` False)
        """
        gym.Env.reset(self, seed=seed)  # Gymnasium's np_random; the scene draws from ScoopGranular's generator
        raw = self.recorder.reset(seed=seed) if self.recorder is not None else self.env.reset(seed=seed)
        self.hold.reset()
        self.robosuite_obs = raw
        return self._observation(raw), {**self.env.scoop_info(), "is_success": False}

    def step(self, action: np.ndarray) -> tuple[np.ndarray | dict, float, bool, bool, dict]:
        """
        One control step. ``terminated``: success held (the suite's rule, ``info["is_success"]``) or a physics
        error; ``truncated``: the horizon reached. ``info`` holds the task's metrics (grains_in_spoon,
        grains_spilled, stage, success: this step's own, ...) and ``is_success``.
        """
        raw, reward, done, info = (self.recorder or self.env).step(action)
        info = dict(info)  # the recorder keeps the env's own
        held = self.hold.update(info)
        terminated = held or bool(info.get("physics_error"))
        info["is_success"] = held if self.hold.steps is not None else bool(info.get("success"))
        self.robosuite_obs = raw
        return self._observation(raw), float(reward), terminated, bool(done) and not terminated, info

    def render(self) -> np.ndarray | None:
        """With render_mode "rgb_array", a frame (height, width, 3) of render_camera, upright; else None."""
        if self.render_mode is None:
            return None
        height, width = self.render_size
        camera = (self.env.render_camera or ["agentview"])[0]  # robosuite keeps a list
        frame = self.env.sim.render(camera_name=camera, height=height, width=width)
        return np.ascontiguousarray(frame[::-1] if robosuite.macros.IMAGE_CONVENTION == "opengl" else frame)

    def _state(self, raw: dict) -> np.ndarray:
        return np.concatenate([np.asarray(raw[k], dtype=np.float64).ravel() for k in self.keys])

    def _images(self, raw: dict) -> dict[str, np.ndarray]:
        """Every camera observable (image, depth, segmentation), upright: robomimic_obs's conversion, as stored."""
        obs = robomimic_obs.observation(self.env, raw)
        cameras = {k for k, o in self.env._observables.items() if o.modality == "image"}
        return {k: v for k, v in obs.items() if k in cameras}

    def _observation(self, raw: dict) -> np.ndarray | dict:
        if self.obs_mode == "state":
            return self._state(raw)
        return {"state": self._state(raw), **self._images(raw)}


def _image_space(sample: np.ndarray) -> spaces.Box:
    """uint8 images 0-255, depth normalized to [0, 1], segmentation ids (integers) over their dtype's range."""
    if sample.dtype == np.uint8:
        low, high = 0, 255
    elif np.issubdtype(sample.dtype, np.integer):
        low, high = np.iinfo(sample.dtype).min, np.iinfo(sample.dtype).max
    else:
        low, high = 0.0, 1.0
    return spaces.Box(low=low, high=high, shape=sample.shape, dtype=sample.dtype)


def register_gym_env() -> None:
    """Registers GYM_ENV_ID with Gymnasium (once; importing veragmil_suite calls it)."""
    if GYM_ENV_ID not in gym.registry:
        gym.register(id=GYM_ENV_ID, entry_point=f"{__name__}:ScoopGranularGymEnv")
