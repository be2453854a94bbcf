"""Dataset tools on files recorded by veragmil_suite.data.recording: info, merge, split, replay, render-obs,
drop-noops, and
robomimic's own get_dataset_info through our entry point (its playback_dataset and dataset_states_to_obs:
test_robomimic_multi_food.py, on a file of several foods)."""

import json
import shutil

import h5py
import imageio
import numpy as np
import pytest
from helpers.programs import run_program
from helpers.recording import CAMERA_SIZE, record_file, tiny_env_kwargs

from veragmil_suite.data.schema import open_dataset
from veragmil_suite.scripts.dataset_tools import (
    drop_noops_main,
    info_main,
    merge_main,
    render_obs_main,
    replay_main,
    split_main,
)

# one worker runs this file's tests: its module fixtures are built once (make test: --dist loadgroup)
pytestmark = pytest.mark.xdist_group("dataset_tools")

STEPS = 10


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("tools")
    pasta, rice = root / "pasta.hdf5", root / "rice.hdf5"
    record_file(pasta, episodes=2, steps=STEPS)
    record_file(rice, episodes=2, steps=STEPS, seed=1, env_kwargs=tiny_env_kwargs(food="rice"))
    return pasta, rice


def test_info_reports_demos_foods_success_and_obs(files, capsys):
    pasta, _ = files
    assert info_main([str(pasta), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["demos"] == 2 and s["transitions"] == 2 * STEPS
    assert s["foods"] == {"pasta": 2} and s["devices"] == {"scripted": 2}
    assert s["success_rate"] == 0.0 and s["attempts"] == 2  # ten steps never reach the post-scoop pose
    assert s["length_steps"] == {"mean": STEPS, "min": STEPS, "max": STEPS}
    assert s["obs_keys"]["overhead_image"] == [[CAMERA_SIZE, CAMERA_SIZE, 3], "uint8"]
    assert s["obs_keys"]["object"] == [[15], "float64"]
    assert s["filter_keys"]["pasta"] == 2 and s["filter_keys"]["train"] + s["filter_keys"]["valid"] == 2
    assert s["env"]["controller"] == "OSC_POSE" and s["env"]["control_freq"] == 20
    assert info_main([str(pasta), "--verbose"]) == 0
    text = capsys.readouterr().out
    assert "per food" in text and "demo_1" in text and "overhead_image" in text


def test_merge_renumbers_and_keeps_each_demos_provenance(files, tmp_path, capsys):
    pasta, rice = files
    merged = tmp_path / "merged.hdf5"
    killed = tmp_path / ".merged.hdf5.deadbeef.writing"  # what a merge killed before this one left
    killed.write_bytes(b"half a merge")
    assert merge_main([str(pasta), str(rice), "--output", str(merged)]) == 0
    assert not killed.exists()  # the file's next write removes it
    with open_dataset(merged) as f:
        data = f["data"]
        assert sorted(data.keys()) == ["demo_0", "demo_1", "demo_2", "demo_3"]
        assert [data[f"demo_{i}"].attrs["food"] for i in range(4)] == ["pasta", "pasta", "rice", "rice"]
        assert data["demo_2"].attrs["merged_from"] == f"{rice}:demo_0"
        assert json.loads(data["demo_3"].attrs["env_args"])["env_kwargs"]["food"] == "rice"
        with h5py.File(rice) as src:
            np.testing.assert_array_equal(data["demo_3/states"][()], src["data/demo_1/states"][()])
            np.testing.assert_array_equal(
                data["demo_3/obs/overhead_image"][()], src["data/demo_1/obs/overhead_image"][()]
            )
        assert data.attrs["total"] == 4 * STEPS
        assert json.loads(data.attrs["foods"]) == ["pasta", "rice"]
        variants = json.loads(data.attrs["env_args"])["env_kwargs_variants"]
        assert variants == [dict(env_kwargs=dict(food="pasta"), demos=2), dict(env_kwargs=dict(food="rice"), demos=2)]
        assert len(json.loads(data.attrs["attempts"])) == 4
        masks = {k: sorted(x.decode() for x in f["mask"][k][()]) for k in f["mask"]}
        assert masks["rice"] == ["demo_2", "demo_3"] and masks["pasta"] == ["demo_0", "demo_1"]
        assert sorted(masks["train"] + masks["valid"]) == [f"demo_{i}" for i in range(4)]

    # another control rate cannot share a file: refused, and nothing is left behind
    other = tmp_path / "other.hdf5"
    shutil.copy(rice, other)
    with h5py.File(other, "a") as f:
        meta = json.loads(f["data"].attrs["env_args"])
        meta["env_kwargs"]["control_freq"] = 60
        f["data"].attrs["env_args"] = json.dumps(meta)
    capsys.readouterr()
    bad = tmp_path / "bad.hdf5"
    assert merge_main([str(pasta), str(other), "--output", str(bad)]) == 2
    assert "control_freq" in capsys.readouterr().err
    assert not bad.exists() and not list(tmp_path.glob("*.partial"))
    assert merge_main([str(pasta), str(rice), "--output", str(merged)]) == 2  # no silent overwrite


def test_split_with_a_ratio_and_within_a_filter_key(files, tmp_path):
    pasta, rice = files
    merged = tmp_path / "split.hdf5"
    assert merge_main([str(pasta), str(rice), "--output", str(merged)]) == 0
    assert split_main([str(merged), "--ratio", "0.5", "--seed", "3"]) == 0
    with h5py.File(merged) as f:
        train, valid = ({x.decode() for x in f["mask"][k][()]} for k in ("train", "valid"))
        assert len(train) == len(valid) == 2 and not train & valid
    assert split_main([str(merged), "--ratio", "0.5", "--filter-key", "rice"]) == 0
    with h5py.File(merged) as f:
        rice_train, rice_valid = ({x.decode() for x in f["mask"][k][()]} for k in ("rice_train", "rice_valid"))
        assert rice_train | rice_valid == {"demo_2", "demo_3"} and len(rice_valid) == 1
    assert split_main([str(merged), "--filter-key", "quinoa"]) == 2


def test_replay_writes_a_video_and_confirms_exact_replay(files, tmp_path, capsys):
    pasta, _ = files
    video = tmp_path / "replay.mp4"
    args = [str(pasta), "--output", str(video), "--camera", "overhead", "--size", "64", "--use-actions"]
    assert replay_main(args) == 0
    out = capsys.readouterr().out
    assert out.count("action replay exact (largest state error 0)") == 2
    frames = imageio.mimread(video, memtest=False)
    assert len(frames) == 2 * STEPS and frames[0].shape == (64, 64, 3)
    assert np.std(frames[0]) > 5  # a rendered scene, not a blank
    assert replay_main([str(pasta), "--output", str(tmp_path / "x.mp4"), "--camera", "nowhere"]) == 2
    assert "unknown camera 'nowhere'; accepted: " in capsys.readouterr().err


def test_render_obs_reproduces_the_recording_and_renders_other_cameras(files, tmp_path):
    pasta, _ = files
    same = tmp_path / "same.hdf5"
    size = str(CAMERA_SIZE)
    assert render_obs_main([str(pasta), "--output", str(same), "--cameras", "overhead", "--size", size, "--depth"]) == 0
    with h5py.File(pasta) as a, open_dataset(same) as b:
        for name in ("demo_0", "demo_1"):
            for key in ("overhead_image", "overhead_depth"):
                np.testing.assert_array_equal(b[f"data/{name}/obs/{key}"][()], a[f"data/{name}/obs/{key}"][()])
                np.testing.assert_array_equal(
                    b[f"data/{name}/next_obs/{key}"][:-1], a[f"data/{name}/next_obs/{key}"][:-1]
                )
                # the last next_obs is simulated again, one step from the last state with the controllers aimed at
                # it: round-off (the solver's warm start is not in a state), not the arm pulled elsewhere
                # (before: 144 pixels off by up to 128 levels): images to a few levels at a few pixels, depth to 1e-5
                new, recorded = [f[f"data/{name}/next_obs/{key}"][-1].astype(float) for f in (b, a)]
                off = np.abs(new - recorded)
                if key == "overhead_image":
                    assert off.max() <= 4 and (off > 1).mean() <= 0.005, (off.max(), (off > 1).sum())
                else:
                    assert off.max() <= 1e-5, off.max()
            for key in ("states", "actions", "obs/robot0_eef_pos", "obs/object"):
                np.testing.assert_array_equal(b[f"data/{name}/{key}"][()], a[f"data/{name}/{key}"][()])

    other = tmp_path / "other.hdf5"
    assert (
        render_obs_main([str(pasta), "-o", str(other), "--cameras", "agentview", "overhead", "--size", "48", "64"]) == 0
    )
    with open_dataset(other) as f:
        obs = f["data/demo_0/obs"]
        assert obs["agentview_image"].shape == (STEPS, 48, 64, 3)
        assert obs["overhead_image"].shape == (STEPS, 48, 64, 3)
        assert "overhead_depth" not in obs
        kwargs = json.loads(f["data"].attrs["env_args"])["env_kwargs"]
        assert kwargs["camera_names"] == ["agentview", "overhead"] and kwargs["camera_heights"] == 48
        assert kwargs["camera_widths"] == 64 and kwargs["camera_depths"] is False


def test_drop_noops_keeps_every_other_step_joins_next_obs_and_leaves_out_an_all_noop_demo(files, tmp_path, capsys):
    """A teleoperator's released input (zero actions) is cut out of every per-step array; next_obs of the step
    before a cut is the observation after it; a demo of pauses only leaves the file and its masks."""
    pasta, _ = files
    paused = tmp_path / "paused.hdf5"
    shutil.copy(pasta, paused)
    cut = [2, 3, STEPS - 1]  # a pause of two steps and the last step
    with h5py.File(paused, "r+") as f:
        actions = f["data/demo_0/actions"][()]
        actions[cut] = 0.0
        actions[5] = 0.004  # small, not zero: kept unless the threshold takes it
        f["data/demo_0/actions"][...] = actions
        f["data/demo_1/actions"][...] = 0.0
    out = tmp_path / "no_noops.hdf5"
    assert drop_noops_main([str(paused), "--output", str(out)]) == 0
    assert f"dropped {len(cut) + STEPS} no-op steps of {2 * STEPS}" in capsys.readouterr().out
    keep = [i for i in range(STEPS) if i not in cut]
    with h5py.File(paused) as a, open_dataset(out) as b:
        assert list(b["data"]) == ["demo_0"] and b["data"].attrs["total"] == len(keep)
        src, dst = a["data/demo_0"], b["data/demo_0"]
        assert dst.attrs["num_samples"] == len(keep) and dst.attrs["noop_steps_dropped"] == len(cut)
        for key in ("actions", "states", "rewards", "obs/robot0_eef_pos", "obs/object", "obs/overhead_image"):
            np.testing.assert_array_equal(dst[key][()], src[key][()][keep])
        assert dst["obs/overhead_image"].compression == src["obs/overhead_image"].compression == "gzip"
        for key in ("robot0_eef_pos", "overhead_image"):
            # each kept step's next observation is the next kept step's observation; the last is the demo's own
            np.testing.assert_array_equal(dst[f"next_obs/{key}"][:-1], src[f"obs/{key}"][()][keep[1:]])
            np.testing.assert_array_equal(dst[f"next_obs/{key}"][-1], src[f"next_obs/{key}"][STEPS - 1])
        assert dst["dones"][-1] == src["dones"][STEPS - 1]
        for key, members in b["mask"].items():
            assert set(members[()]) <= {b"demo_0"}, key
        assert {m.decode() for k in ("train", "valid") for m in b["mask"][k][()]} == {"demo_0"}
        record = json.loads(b["data"].attrs["noops_dropped"])
        assert record["steps_before"] == 2 * STEPS and record["steps_after"] == len(keep)
    info = _robomimic("veragmil-robomimic-dataset-info", "--dataset", out, cwd=tmp_path)
    assert "total trajectories: 1" in info and f"total transitions: {len(keep)}" in info
    # a threshold takes small actions too
    loose = tmp_path / "loose.hdf5"
    assert drop_noops_main([str(paused), "-o", str(loose), "--threshold", "0.01"]) == 0
    with h5py.File(loose) as f:
        assert f["data/demo_0"].attrs["num_samples"] == len(keep) - 1

    # bad input: one line, status 2, and the file already there is left as it was
    before = out.read_bytes()
    assert drop_noops_main([str(paused), "-o", str(out)]) == 2
    assert "exists (use --force to overwrite it)" in capsys.readouterr().err
    assert drop_noops_main([str(paused), "-o", str(paused), "--force"]) == 2
    assert "is also the input: write the copy to a new file" in capsys.readouterr().err
    assert drop_noops_main([str(paused), "-o", str(tmp_path / "x.hdf5"), "--threshold", "-0.1"]) == 2
    assert "--threshold" in capsys.readouterr().err and not (tmp_path / "x.hdf5").exists()
    assert out.read_bytes() == before


def test_drop_noops_keep_held_keeps_the_noops_at_which_success_held(files, tmp_path, capsys):
    """--keep-held: a no-op whose reward is the env's success reward (its reward_scale), the hold at the goal,
    stays; by default it goes with the other pauses. A shaped reward below it is no success."""
    pasta, _ = files
    held = tmp_path / "held.hdf5"
    shutil.copy(pasta, held)
    with h5py.File(held, "r+") as f:
        actions, rewards = f["data/demo_0/actions"][()], f["data/demo_0/rewards"][()]
        actions[[1, 6, 7, 8]] = 0.0  # a pause on the way, then the hold at the goal
        rewards[:] = 0.5  # shaped, below success
        rewards[[6, 7, 8]] = 2.0  # success held, under reward_scale 2
        f["data/demo_0/actions"][...], f["data/demo_0/rewards"][...] = actions, rewards
        env_args = json.loads(f["data"].attrs["env_args"])
        env_args["env_kwargs"]["reward_scale"] = 2.0
        f["data"].attrs["env_args"] = json.dumps(env_args)
    kept = tmp_path / "kept.hdf5"
    assert drop_noops_main([str(held), "-o", str(kept), "--keep-held"]) == 0
    assert "dropped 1 no-op steps of 20 (5%); kept 3 at which the task's success held" in capsys.readouterr().out
    with h5py.File(held) as a, open_dataset(kept) as b:
        keep = [i for i in range(STEPS) if i != 1]
        np.testing.assert_array_equal(b["data/demo_0/actions"][()], a["data/demo_0/actions"][()][keep])
        assert b["data/demo_0"].attrs["held_noop_steps_kept"] == 3
        record = json.loads(b["data"].attrs["noops_dropped"])
        assert record["keep_held"] is True and record["held_noop_steps_kept"] == 3
    dropped = tmp_path / "dropped.hdf5"
    assert drop_noops_main([str(held), "-o", str(dropped)]) == 0
    assert "dropped 4 no-op steps of 20 (20%)\n" in capsys.readouterr().out
    with open_dataset(dropped) as f:
        assert f["data/demo_0"].attrs["num_samples"] == STEPS - 4
        assert json.loads(f["data"].attrs["noops_dropped"])["keep_held"] is False
    # under robosuite's default reward_scale (1) the same rewards of 2 are success too; of 0.5, not
    with h5py.File(held, "r+") as f:
        env_args["env_kwargs"].pop("reward_scale")
        f["data"].attrs["env_args"] = json.dumps(env_args)
        f["data/demo_0/rewards"][[6, 7]] = 0.5
    assert drop_noops_main([str(held), "-o", str(kept), "--force", "--keep-held"]) == 0
    assert "dropped 3 no-op steps of 20 (15%); kept 1 at which" in capsys.readouterr().out


def _robomimic(command, *args, cwd):
    return run_program(command, *args, cwd=cwd).stdout


def test_robomimics_dataset_info_reads_our_files(files, tmp_path):
    pasta, _ = files
    dataset = tmp_path / "pasta.hdf5"
    shutil.copy(pasta, dataset)
    out = _robomimic("veragmil-robomimic-dataset-info", "--dataset", dataset, cwd=tmp_path)
    assert "total trajectories: 2" in out and f"total transitions: {2 * STEPS}" in out
    assert "filter key pasta with 2 demos" in out and '"env_name": "ScoopGranular"' in out
