"""veragmil_suite: scooping granular food with a spoon, as a robosuite task plugin."""

import os

from setuptools import find_packages, setup

# Recorded demonstrations replay bit-exactly only on the MuJoCo that recorded them, and robosuite 1.5.2
# breaks with mujoco >= 3.12: one exact version is pinned, 3.8.x for its island sleeping (resting grains cost nothing).
MUJOCO_VERSION = "3.8.1"
# the Ray the tests ran with: one version on the driver and every node of a cluster (Ray's own requirement)
RAY_VERSION = "2.60.0"

# Folders of data installed as packages of their own (setuptools installs data only as a package's files):
# models/assets and configs/json stay at the repository's top level and become veragmil_suite.assets (one
# package per folder) and veragmil_suite.configs, so a non-editable install finds them from any directory; the
# WebXR page's folder has no __init__.py and is the package veragmil_suite.devices.vr.web.
ASSET_DIRS = sorted(d for d, _, _ in os.walk(os.path.join("models", "assets")))
DATA_PACKAGES = {"veragmil_suite.assets" + d[len("models/assets") :].replace(os.sep, "."): d for d in ASSET_DIRS}
DATA_PACKAGES["veragmil_suite.configs"] = os.path.join("configs", "json")
WEB_PACKAGE = "veragmil_suite.devices.vr.web"

setup(
    name="veragmil_suite",
    version="0.1.0",
    description="robosuite task plugin for scooping and carrying granular food with a spoon (VERAGMIL on MuJoCo)",
    python_requires=">=3.10",
    packages=[*find_packages(include=["veragmil_suite", "veragmil_suite.*"]), *DATA_PACKAGES, WEB_PACKAGE],
    package_dir=DATA_PACKAGES,
    package_data={package: ["*"] for package in [*DATA_PACKAGES, WEB_PACKAGE]},
    include_package_data=True,
    install_requires=[
        "robosuite==1.5.2",
        f"mujoco=={MUJOCO_VERSION}",
        "robomimic==0.3.0",
        # the Gymnasium API (veragmil_suite.wrappers.gym_env); robosuite's GymWrapper imports it
        "gymnasium==1.4.0",
        "torch>=2.0",
        "h5py>=3.8",
        # robosuite 1.5.2 requires mink==0.0.5, which requires numpy<2 (stated so the resolver's pick is no surprise)
        "numpy>=1.24,<2",
        "hidapi>=0.14",
        "aiohttp>=3.9",
        "tqdm>=4.60",
        "imageio>=2.30",
        "imageio-ffmpeg>=0.4.9",
        "matplotlib>=3.7",
        # the exact sign test of paired comparisons (veragmil_suite.evaluation.reporting); robosuite requires it too
        "scipy>=1.10",
        # a stopped study's stage processes and everything under them (veragmil_suite.utils.termination); robomimic
        # requires it too
        "psutil>=5.9",
        # Diffusion Policy's noise schedulers and EMA (veragmil_suite.learning.algos), as robomimic 0.5 uses them;
        # 0.36 is the newest that shares huggingface-hub (< 0.36) with lerobot-dataset 0.4.4 (extra lerobot)
        "diffusers==0.36.0",
    ],
    extras_require={
        # pytest-timeout: make test gives each test a deadline, so a hung test fails with its stack, not a hung CI
        # ruff pinned: make test checks the tree's formatting, and the formatter's output moves between releases
        # pytest pinned to 9.1.1: on 9.2.0 pytest-xdist 3.8.0's --dist loadgroup silently stops grouping
        # (pytest-dev/pytest-xdist#1386), and make test relies on it (tests/test_make_test.py checks it)
        "test": ["pytest==9.1.1", "pytest-xdist==3.8.0", "pytest-timeout==2.4.0", "ruff==0.17.6"],
        # ray: --ray of veragmil-collect, veragmil-evaluate and veragmil-study (veragmil_suite.utils.distributed)
        "ray": [f"ray=={RAY_VERSION}"],
        # the Unitree G1 (robots="G1FixedLowerBody" or "G1ArmsOnly"); robosuite imports it when it is installed
        "humanoid": ["robosuite-models==1.0.0"],
        # lerobot: veragmil-export-lerobot writes LeRobotDatasets with the standalone LeRobotDataset package (no
        # torch pin, unlike lerobot itself). Beside numpy<2: opencv-python-headless 4.12 and pyarrow 26 need NumPy 2
        # (pyarrow's metadata does not say so). torchcodec decodes the videos (torchvision 0.28 no longer can); 0.13
        # is the release built for torch 2.13 and needs FFmpeg's libraries (scripts/install_system_deps.sh --test).
        "lerobot": [
            "lerobot-dataset==0.4.4",
            "opencv-python-headless<4.12",
            "pyarrow<26",
            "torchcodec==0.13.0",
        ],
    },
    entry_points={
        "console_scripts": [
            "veragmil-collect=veragmil_suite.scripts.collect_human_demonstrations:main",
            "veragmil-dataset-info=veragmil_suite.scripts.dataset_tools:info_main",
            "veragmil-merge=veragmil_suite.scripts.dataset_tools:merge_main",
            "veragmil-split=veragmil_suite.scripts.dataset_tools:split_main",
            "veragmil-replay=veragmil_suite.scripts.dataset_tools:replay_main",
            "veragmil-render-obs=veragmil_suite.scripts.dataset_tools:render_obs_main",
            "veragmil-drop-noops=veragmil_suite.scripts.dataset_tools:drop_noops_main",
            "veragmil-train=veragmil_suite.scripts.robomimic_entry:train_main",
            "veragmil-run-agent=veragmil_suite.scripts.robomimic_entry:run_agent_main",
            "veragmil-robomimic-dataset-info=veragmil_suite.scripts.robomimic_entry:get_dataset_info_main",
            "veragmil-robomimic-playback=veragmil_suite.scripts.robomimic_entry:playback_dataset_main",
            "veragmil-robomimic-states-to-obs=veragmil_suite.scripts.robomimic_entry:dataset_states_to_obs_main",
            "veragmil-evaluate=veragmil_suite.scripts.evaluate:main",
            "veragmil-study=veragmil_suite.scripts.study:main",
            "veragmil-quickstart=veragmil_suite.scripts.quickstart:main",
            "veragmil-bench=veragmil_suite.scripts.bench:main",
            "veragmil-export-lerobot=veragmil_suite.scripts.export_lerobot:main",
            "veragmil-pool-results=veragmil_suite.scripts.pool_results:main",
            "veragmil-publish-results=veragmil_suite.scripts.publish_results:main",
        ]
    },
)
