"""
ScoopGranular demonstration files (robomimic's HDF5 schema, veragmil_suite.data.recording) as LeRobotDatasets (format
v3.0), written by the standalone ``lerobot-dataset`` package's own writer (``LeRobotDataset.create``,
``add_frame``, ``save_episode``, ``finalize``): the extra ``lerobot`` of setup.py.

Each demo becomes an episode, each step a frame, at the control rate:

    action                          the stored action (OSC_POSE deltas in [-1, 1]), float32
    observation.state               the robot's own sensing (joints, end effector, wrist force-torque): every
                                    ``robot0_*`` low-dim key, in name order, float32
    observation.environment_state   robosuite's object-state (``object``: the task's bowl, spoon and target keys),
                                    then the task's observables outside it that the file holds (the turn to the
                                    post-scoop pose, the piece size: observation_sets.GOAL_OBSERVABLES), float32
    observation.images.<camera>     each ``<camera>_image`` the file holds, as a video
    next.reward, next.done          the reward and done flag of the step
    episode.food, episode.<metric>  the demo's food and metrics (success, spilled pieces and volume, completion
                                    time, stage, ...), the same on every frame of the episode
    task                            "Scoop <food> from the bowl with the spoon": one task per food

The export takes the images the file holds: a file recorded without cameras gives an episode of states only
(``veragmil-render-obs`` renders cameras from the states first). Depth images are not exported (no video codec
keeps metres). Floats are stored as float32, LeRobot's own dtype for states and actions.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import os
import shutil
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm import tqdm

from veragmil_suite.data.schema import METRIC_KEYS, DatasetError, demo_names, filter_key_demos, open_dataset
from veragmil_suite.learning import robomimic_compat
from veragmil_suite.learning.observation_sets import GOAL_OBSERVABLES
from veragmil_suite.utils.whole_files import put_folder_in_place, recover_folder

if TYPE_CHECKING:
    import h5py

STATE_PREFIX = "robot0_"
ENVIRONMENT_STATE_KEY = "object"
IMAGE_SUFFIX = "_image"
DEPTH_SUFFIX = "_depth"
BOOL_HISTOGRAM_WARNING = "Converting input from bool to"
STATS_MODULE = "ledataset.datasets.compute_stats"
# OSC_POSE's six action dimensions (veragmil_suite.controllers.scoop_config)
ACTION_NAMES = ["dx", "dy", "dz", "drx", "dry", "drz"]
# LeRobotDataset.create's video codecs; libsvtav1 (AV1) is its default and the format's usual one
VIDEO_CODECS = ("libsvtav1", "h264", "hevc")
# SVT-AV1's own log threshold ($SVT_LOG): errors only. Its info banner of settings per video and its warnings
# (lerobot-dataset's preset 12 "mapped to" 10; no thread priorities in a container) say nothing to act on.
SVT_LOG_ERRORS = "1"
# each metric of schema.METRIC_KEYS as a LeRobot dtype
METRIC_DTYPES = {
    "success": "bool",
    "grains_in_spoon": "int64",
    "grains_spilled": "int64",
    "spilled_volume_cm3": "float32",
    "spill_fraction": "float32",
    "scooped_volume_cm3": "float32",
    "spoon_volume_cm3": "float32",
    "spoon_mass_g": "float32",
    "spilled_mass_g": "float32",
    "completion_time_s": "float32",
    "physics_error": "string",
    "stage": "string",
}


def task_of(food: str) -> str:
    """The episode's task, as LeRobot's language-conditioned policies read it."""
    return f"Scoop {food} from the bowl with the spoon"


def _metric_value(key: str, value) -> object:
    """A metric as add_frame takes it (METRIC_DTYPES)."""
    dtype = METRIC_DTYPES[key]
    if dtype == "string":
        return value.decode() if isinstance(value, bytes) else str(value)
    return np.array([value], dtype=bool if dtype == "bool" else dtype)


@dataclass
class ExportLayout:
    """Which keys of the file go to which LeRobot features, read from the file's first exported demo."""

    state_keys: list[str]
    environment_keys: list[str]
    cameras: list[str]
    action_dim: int
    metric_dtypes: dict[str, str]
    skipped_keys: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, demo: h5py.Group) -> ExportLayout:
        obs = demo["obs"]
        state_keys = sorted(k for k in obs if k.startswith(STATE_PREFIX) and obs[k].ndim == 2 and obs[k].shape[1])
        cameras = sorted(k[: -len(IMAGE_SUFFIX)] for k in obs if k.endswith(IMAGE_SUFFIX))
        metrics = {k: METRIC_DTYPES[k] for k in METRIC_KEYS if k in demo.attrs}
        return cls(
            state_keys=state_keys,
            environment_keys=[k for k in (ENVIRONMENT_STATE_KEY, *GOAL_OBSERVABLES) if k in obs],
            cameras=cameras,
            action_dim=int(demo["actions"].shape[1]),
            metric_dtypes=metrics,
            skipped_keys=sorted(k for k in obs if k.endswith(DEPTH_SUFFIX)),
        )

    def features(self, demo: h5py.Group) -> dict:
        """LeRobotDataset.create's ``features`` for this layout (``demo`` gives the shapes)."""
        obs = demo["obs"]
        names = [f"{k}_{i}" for k in self.state_keys for i in range(obs[k].shape[1])]
        features = {
            "action": dict(
                dtype="float32",
                shape=(self.action_dim,),
                names=ACTION_NAMES if self.action_dim == len(ACTION_NAMES) else None,
            ),
            "observation.state": dict(dtype="float32", shape=(len(names),), names=names),
            "next.reward": dict(dtype="float32", shape=(1,), names=None),
            "next.done": dict(dtype="bool", shape=(1,), names=None),
            "episode.food": dict(dtype="string", shape=(1,), names=None),
        }
        if self.environment_keys:
            width = sum(obs[k].shape[1] for k in self.environment_keys)
            features["observation.environment_state"] = dict(dtype="float32", shape=(width,), names=None)
        for camera in self.cameras:
            features[f"observation.images.{camera}"] = dict(
                dtype="video", shape=tuple(obs[camera + IMAGE_SUFFIX].shape[1:]), names=["height", "width", "channels"]
            )
        for key, dtype in self.metric_dtypes.items():
            features[f"episode.{key}"] = dict(dtype=dtype, shape=(1,), names=None)
        return features

    def frames(self, demo: h5py.Group, food: str) -> Iterator[dict[str, Any]]:
        """The demo's frames, as add_frame takes them."""
        obs = demo["obs"]
        state = np.concatenate([obs[k][()] for k in self.state_keys], axis=1).astype(np.float32)
        environment = (
            np.concatenate([obs[k][()] for k in self.environment_keys], axis=1).astype(np.float32)
            if self.environment_keys
            else None
        )
        actions = demo["actions"][()].astype(np.float32)
        rewards = demo["rewards"][()].astype(np.float32)
        dones = demo["dones"][()].astype(bool)
        episode = {f"episode.{k}": _metric_value(k, demo.attrs[k]) for k in self.metric_dtypes}
        images = {camera: obs[camera + IMAGE_SUFFIX] for camera in self.cameras}
        for t in range(actions.shape[0]):
            frame = {
                "action": actions[t],
                "observation.state": state[t],
                "next.reward": rewards[t : t + 1],
                "next.done": dones[t : t + 1],
                "episode.food": food,
                "task": task_of(food),
                **episode,
            }
            if environment is not None:
                frame["observation.environment_state"] = environment[t]
            for camera, frames in images.items():
                frame[f"observation.images.{camera}"] = frames[t]
            yield frame


@dataclass
class ExportSummary:
    """What an export wrote."""

    root: Path
    repo_id: str
    episodes: int
    frames: int
    fps: int
    cameras: list[str]
    foods: dict[str, int]
    skipped_keys: list[str]


def _demo_food(demo, default: str) -> str:
    if "food" in demo.attrs:
        value = demo.attrs["food"]
        return value.decode() if isinstance(value, bytes) else str(value)
    if "env_args" in demo.attrs:
        return str(json.loads(demo.attrs["env_args"])["env_kwargs"].get("food", default))
    return default


def _select(f, filter_key: str | None) -> list[str]:
    names = demo_names(f)
    if filter_key is None:
        return names
    keep = set(filter_key_demos(f, filter_key))
    return [n for n in names if n in keep]


class ExtraNotInstalled(RuntimeError):
    """The extra ``lerobot`` of setup.py is not installed."""


def _lerobot_dataset_class():
    """lerobot-dataset's LeRobotDataset, imported quietly.

    Raises:
        ExtraNotInstalled: [lerobot-dataset is not installed]
    """
    if importlib.util.find_spec("ledataset") is None:
        raise ExtraNotInstalled('the lerobot-dataset package is not installed: pip install ".[lerobot]"')
    robomimic_compat.install()  # torchvision, which lerobot-dataset imports, beside the CPU torch wheel
    os.environ.setdefault("SVT_LOG", SVT_LOG_ERRORS)
    import datasets  # optional extra: lerobot
    from ledataset.datasets.lerobot_dataset import LeRobotDataset  # optional extra: lerobot

    datasets.disable_progress_bars()  # a bar per episode written, beside ours
    return LeRobotDataset


def export_lerobot(
    dataset: str | Path,
    output: str | Path,
    repo_id: str | None = None,
    filter_key: str | None = None,
    vcodec: str = VIDEO_CODECS[0],
    force: bool = False,
    progress: bool = True,
) -> ExportSummary:
    """
    Writes the demos of ``dataset`` (those of ``filter_key``, else all) as a LeRobotDataset in the folder ``output``
    (replaced when ``force``), named ``repo_id`` (default: veragmil/<file name>).

    Raises:
        DatasetError: [not a ScoopGranular dataset, no demos to export, a demo whose keys or shapes differ from
            the first's, a control rate that is no whole number of Hz, ``output`` exists and not ``force``, or is
            no earlier export, or holds ``dataset``, or is the file system's root]
        ValueError: [an unknown ``vcodec``]
        ExtraNotInstalled: [lerobot-dataset is not installed]
    """
    if vcodec not in VIDEO_CODECS:
        raise ValueError(f"unknown video codec {vcodec!r}; accepted: {', '.join(VIDEO_CODECS)}")
    named, output = output, Path(os.path.abspath(output))  # ``.`` and ``a/..`` by the folder they name
    if not output.name:
        raise DatasetError(f"{named}: the export needs a folder of its own, not the file system's root")
    # written beside ``output`` (hidden) and put in its place once complete: a failed export leaves no half dataset;
    # what a killed export left (this name, or the export it replaced, set aside) is seen to first
    partial = output.with_name(f".{output.name}.partial")
    recover_folder(output)
    if Path(dataset).resolve().is_relative_to(output.resolve()):
        raise DatasetError(f"{named} holds the input {dataset}: export to another folder")
    if output.exists() and not force:
        raise DatasetError(f"{named} exists (use --force to replace it)")
    if output.exists() and not (output / "meta" / "info.json").is_file():
        raise DatasetError(
            f"{named} is not a LeRobot export (no meta/info.json): --force replaces only an earlier export; "
            "export to a new folder"
        )
    with open_dataset(dataset) as f:
        names = _select(f, filter_key)
        if not names:
            raise DatasetError(f"{dataset}: no demos to export")
        data = f["data"]
        env_kwargs = json.loads(data.attrs["env_args"])["env_kwargs"]
        control_freq = float(env_kwargs.get("control_freq", 20))
        if control_freq != int(control_freq):
            raise DatasetError(
                f"{dataset}: control rate {control_freq:g} Hz; LeRobot stores a whole number of frames/s"
            )
        first = data[names[0]]
        layout = ExportLayout.of(first)
        features = layout.features(first)
        LeRobotDataset = _lerobot_dataset_class()
        robots = env_kwargs.get("robots", "")
        repo_id = repo_id or f"veragmil/{Path(dataset).stem}"
        if partial.exists():
            shutil.rmtree(partial)
        writer = LeRobotDataset.create(
            repo_id=repo_id,
            fps=int(control_freq),
            features=copy.deepcopy(features),  # create() adds its own features to the dict it is given
            root=partial,
            robot_type=robots if isinstance(robots, str) else ",".join(robots),
            use_videos=True,
            vcodec=vcodec,
        )
        # FFmpeg's own console log (lerobot-dataset hands it back after each encode) above its info lines only
        import av  # optional extra: lerobot (PyAV comes with it)

        av.logging.set_libav_level(av.logging.WARNING)
        foods: dict[str, int] = {}
        total = sum(int(data[n].attrs["num_samples"]) for n in names)
        try:
            with tqdm(total=total, desc="exporting", unit="frame", disable=not progress) as bar:
                for name in names:
                    demo = data[name]
                    if ExportLayout.of(demo) != layout or layout.features(demo) != features:
                        raise DatasetError(f"{dataset}:{name} has other observations or shapes than {names[0]}")
                    food = _demo_food(demo, str(env_kwargs.get("food", "")))
                    for frame in layout.frames(demo, food):
                        writer.add_frame(frame)
                    with warnings.catch_warnings():
                        # lerobot-dataset's statistics take histograms of bool features (next.done, episode.success)
                        # through a uint8 copy, saying so each time
                        warnings.filterwarnings("ignore", BOOL_HISTOGRAM_WARNING, RuntimeWarning, STATS_MODULE)
                        writer.save_episode()
                    foods[food] = foods.get(food, 0) + 1
                    bar.update(int(demo.attrs["num_samples"]))
            writer.finalize()
        except BaseException:
            writer.finalize()
            shutil.rmtree(partial, ignore_errors=True)
            raise
    put_folder_in_place(partial, output)
    return ExportSummary(
        root=output,
        repo_id=repo_id,
        episodes=len(names),
        frames=total,
        fps=int(control_freq),
        cameras=layout.cameras,
        foods=foods,
        skipped_keys=layout.skipped_keys,
    )
