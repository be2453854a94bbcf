"""The pieces of a training's resume (veragmil_suite.learning.training_resume) that a real run exercises only when
killed at the wrong moment: writes interrupted mid-file, the run to resume chosen among several. The whole resume,
killed and bit-exact, is tests/test_training.py::test_a_killed_training_resumes_to_the_weights_of_an_uninterrupted_one.
"""

import os
import time
import types

import pytest

from veragmil_suite.learning import training_resume


def _failing_train_utils(written: bytes):
    """robomimic's train_utils whose save_model writes ``written`` and then fails, as a kill or a full disk would."""

    def save_model(model, config, env_meta, shape_meta, ckpt_path, obs_normalization_stats=None):
        with open(ckpt_path, "wb") as f:
            f.write(written)
        raise OSError(28, "No space left on device")

    return types.SimpleNamespace(save_model=save_model)


def test_a_checkpoint_write_that_fails_leaves_the_earlier_file_and_no_partial(tmp_path):
    checkpoint = tmp_path / "model_epoch_10.pth"
    checkpoint.write_bytes(b"complete")
    utils = training_resume.ResumingTrainUtils(_failing_train_utils(b"trunc"))
    with pytest.raises(OSError, match="No space"):
        utils.save_model(None, None, None, None, str(checkpoint))
    assert checkpoint.read_bytes() == b"complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model_epoch_10.pth"]


def test_a_resume_state_write_that_fails_keeps_the_previous_state(tmp_path, monkeypatch):
    import torch

    training_resume.save(tmp_path, {"format": training_resume.RESUME_FORMAT, "epoch": 3})

    def fail(state, path):
        with open(path, "wb") as f:
            f.write(b"half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(torch, "save", fail)
    with pytest.raises(OSError):
        training_resume.save(tmp_path, {"format": training_resume.RESUME_FORMAT, "epoch": 7})
    monkeypatch.undo()
    assert training_resume.load(tmp_path)["epoch"] == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == [training_resume.RESUME_FILE]


def test_the_run_to_resume_is_the_newest_that_holds_a_state(tmp_path):
    assert training_resume.resumable_run(tmp_path, "exp") is None
    for stamp, age in (("20261130010000", 200), ("20261130020000", 100), ("20261130030000", None)):
        run = tmp_path / "exp" / stamp
        run.mkdir(parents=True)
        if age is not None:  # the newest folder finished: it keeps no state
            (run / training_resume.RESUME_FILE).write_bytes(b"")
            os.utime(run / training_resume.RESUME_FILE, (time.time() - age, time.time() - age))
    assert training_resume.resumable_run(tmp_path, "exp") == tmp_path / "exp" / "20261130020000"


def test_a_resume_state_of_another_format_is_refused_by_name(tmp_path):
    training_resume.save(tmp_path, {"format": 99, "epoch": 1})
    with pytest.raises(ValueError, match="format 99; this version reads 1"):
        training_resume.load(tmp_path)
