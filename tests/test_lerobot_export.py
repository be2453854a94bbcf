"""veragmil-export-lerobot: the sample demonstrations as a LeRobotDataset, read back frame by frame with the
lerobot-dataset package's own LeRobotDataset. Skipped when the extra ``lerobot`` is not installed (make test's
setup installs it)."""

import importlib.util
from pathlib import Path

import h5py
import numpy as np
import pytest

from veragmil_suite.scripts.export_lerobot import main

SAMPLE = Path(__file__).resolve().parent.parent / "demos" / "scoop.hdf5"
# AV1 at lerobot-dataset's default quality (CRF 30) on the sample's 84x84 frames: 28 to 35 dB here
MIN_PSNR_DB = 25.0
MAX_MEAN_ABS_ERROR = 6.0  # of 255

pytestmark = [
    pytest.mark.xdist_group("lerobot_export"),  # one worker: the export fixture is built once
    pytest.mark.skipif(
        importlib.util.find_spec("ledataset") is None or importlib.util.find_spec("torchcodec") is None,
        reason='the lerobot extra is not installed (pip install ".[lerobot]")',
    ),
    # lerobot-dataset stores a scalar feature as an array of shape (1,), which Hugging Face datasets turns into a
    # number with float() / int(): NumPy >= 1.25 calls that deprecated, once per value written or read
    pytest.mark.filterwarnings("ignore:Conversion of an array with ndim > 0:DeprecationWarning:datasets.features"),
]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    root = tmp_path_factory.mktemp("lerobot") / "scoop"
    assert main([str(SAMPLE), "--output-dir", str(root), "--quiet"]) == 0
    from veragmil_suite.learning import robomimic_compat

    robomimic_compat.install()  # torchvision, which lerobot-dataset imports, beside the CPU torch wheel
    from ledataset.datasets.lerobot_dataset import LeRobotDataset

    return LeRobotDataset("veragmil/scoop", root=root, video_backend="torchcodec")


def test_every_frame_reads_back_with_its_action_state_image_food_and_metrics(exported):
    with h5py.File(SAMPLE) as f:
        demos = [f["data"][f"demo_{i}"] for i in range(len(f["data"]))]
        assert exported.meta.total_episodes == len(demos)
        assert exported.meta.info["codebase_version"] == "v3.0"
        assert exported.meta.video_keys == ["observation.images.overhead"]
        assert len(exported) == sum(d["actions"].shape[0] for d in demos)
        arrays = []
        for d in demos:
            obs = d["obs"]
            state = np.concatenate([obs[k][()] for k in sorted(obs) if k.startswith("robot0_")], axis=1)
            arrays.append(
                dict(
                    action=d["actions"][()].astype(np.float32),
                    state=state.astype(np.float32),
                    # object, then the turn to the pose and the piece size (a policy needs the food's size)
                    environment=np.concatenate(
                        [obs[k][()] for k in ("object", "spoon_to_desired_rot", "piece_size")], axis=1
                    ).astype(np.float32),
                    reward=d["rewards"][()].astype(np.float32),
                    done=d["dones"][()].astype(bool),
                    image=obs["overhead_image"][()].astype(np.float64),
                    food=str(d.attrs["food"]),
                    success=bool(d.attrs["success"]),
                    spilled=int(d.attrs["grains_spilled"]),
                    time=np.float32(d.attrs["completion_time_s"]),
                )
            )
    psnrs, errors = [], []
    for i in range(len(exported)):
        frame = exported[i]
        demo = arrays[int(frame["episode_index"])]
        t = int(frame["frame_index"])
        np.testing.assert_array_equal(frame["action"].numpy(), demo["action"][t])
        np.testing.assert_array_equal(frame["observation.state"].numpy(), demo["state"][t])
        np.testing.assert_array_equal(frame["observation.environment_state"].numpy(), demo["environment"][t])
        assert float(frame["next.reward"]) == demo["reward"][t] and bool(frame["next.done"]) == demo["done"][t]
        assert (
            frame["episode.food"] == demo["food"]
            and frame["task"] == f"Scoop {demo['food']} from the bowl with the spoon"
        )
        assert bool(frame["episode.success"]) == demo["success"]
        assert int(frame["episode.grains_spilled"]) == demo["spilled"]
        assert float(frame["episode.completion_time_s"]) == demo["time"]
        image = frame["observation.images.overhead"].permute(1, 2, 0).numpy().astype(np.float64) * 255
        assert image.shape == demo["image"][t].shape
        mse = float(np.mean((image - demo["image"][t]) ** 2))
        psnrs.append(10 * np.log10(255**2 / max(mse, 1e-12)))
        errors.append(float(np.mean(np.abs(image - demo["image"][t]))))
    assert min(psnrs) >= MIN_PSNR_DB, f"worst frame {min(psnrs):.1f} dB"
    assert max(errors) <= MAX_MEAN_ABS_ERROR, f"worst frame's mean error {max(errors):.2f} of 255"


def test_the_episodes_are_the_files_foods(exported):
    tasks = sorted(exported.meta.tasks.index)
    assert tasks == [f"Scoop {food} from the bowl with the spoon" for food in ("barley", "buckwheat", "pasta", "rice")]


def test_an_unknown_filter_key_or_file_is_one_line_naming_the_accepted_and_exit_2(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([str(SAMPLE), "--output-dir", str(out), "--filter-key", "peas"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no filter key 'peas'" in err[0] and "rice" in err[0]
    assert main([str(tmp_path / "none.hdf5"), "--output-dir", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "no such file" in err[-1]  # argparse's usage, then its one error line
    assert not out.exists()


def test_an_unknown_codec_is_refused_by_argparse_naming_the_codecs(tmp_path, capsys):
    assert main([str(SAMPLE), "--output-dir", str(tmp_path / "out"), "--vcodec", "mpeg2"]) == 2
    err = capsys.readouterr().err
    assert "mpeg2" in err and "libsvtav1" in err and "h264" in err and "hevc" in err


def test_an_existing_output_is_kept_without_force(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("kept")
    assert main([str(SAMPLE), "--output-dir", str(out)]) == 2
    assert "exists (use --force" in capsys.readouterr().err and (out / "mine.txt").read_text() == "kept"


def test_force_replaces_only_an_earlier_export_never_a_folder_of_the_users_or_the_inputs(tmp_path, capsys, monkeypatch):
    """--force replaces the output folder whole: it must be an earlier export, not a folder of other files, not the
    folder holding the input, not ``.`` (one line each, exit 2, the folder as it was)."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("kept")
    assert main([str(SAMPLE), "--output-dir", str(mine), "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a LeRobot export (no meta/info.json)" in err[0]
    assert (mine / "notes.txt").read_text() == "kept"
    demos = tmp_path / "demos"
    demos.mkdir()
    dataset = demos / "scoop.hdf5"
    dataset.write_bytes(SAMPLE.read_bytes())
    for output in (demos, tmp_path):
        assert main([str(dataset), "--output-dir", str(output), "--force"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"holds the input {dataset}" in err[0]
    monkeypatch.chdir(demos)
    assert main(["scoop.hdf5", "--output-dir", ".", "--force"]) == 2
    assert "holds the input scoop.hdf5" in capsys.readouterr().err
    assert dataset.read_bytes() == SAMPLE.read_bytes() and sorted(p.name for p in demos.iterdir()) == ["scoop.hdf5"]


def test_every_metric_a_demo_stores_has_a_lerobot_type():
    from veragmil_suite.data.lerobot_export import METRIC_DTYPES
    from veragmil_suite.data.schema import METRIC_KEYS

    assert set(METRIC_DTYPES) == set(METRIC_KEYS)
