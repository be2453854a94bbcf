"""Outputs written whole or not at all, never over their own inputs (veragmil_suite.utils.whole_files)."""

import os

import pytest

from veragmil_suite.utils.whole_files import (
    append_line,
    json_lines,
    put_folder_in_place,
    recover_folder,
    same_file,
    write_text_whole,
    written_whole,
)


def test_a_write_cut_short_leaves_the_file_that_was_there_and_no_temporary_one(tmp_path):
    path = tmp_path / "results.json"
    path.write_text("the earlier evaluation")
    with pytest.raises(RuntimeError), written_whole(path) as partial:
        partial.write_text('{"half": ')
        raise RuntimeError("killed part-way")
    assert path.read_text() == "the earlier evaluation"
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]
    write_text_whole(path, "the new one")
    assert path.read_text() == "the new one"
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]


def test_the_temporary_name_is_hidden_from_searches_by_suffix_unless_the_writer_needs_it(tmp_path):
    with written_whole(tmp_path / "model_epoch_50.pth") as partial:
        assert partial.name.startswith(".") and not partial.name.endswith(".pth")  # no glob("*.pth") takes it
        partial.write_bytes(b"weights")
    with written_whole(tmp_path / "success.png", keep_suffix=True) as partial:
        assert partial.suffix == ".png"  # matplotlib reads the format from it
        partial.write_bytes(b"png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model_epoch_50.pth", "success.png"]


def test_a_name_at_the_length_limit_is_written_whole(tmp_path):
    path = tmp_path / ("n" * (os.pathconf(tmp_path, "PC_NAME_MAX") - len(".json")) + ".json")
    write_text_whole(path, "{}")
    assert path.read_text() == "{}"


def test_same_file_knows_a_file_by_every_name(tmp_path):
    data = tmp_path / "data.hdf5"
    data.write_text("demos")
    (tmp_path / "link.hdf5").hardlink_to(data)
    (tmp_path / "alias.hdf5").symlink_to(data)
    (tmp_path / "sub").mkdir()
    (tmp_path / "other.hdf5").write_text("demos")
    assert same_file(data, tmp_path / "link.hdf5")
    assert same_file(data, tmp_path / "alias.hdf5")
    assert same_file(data, tmp_path / "sub" / ".." / "data.hdf5")
    assert not same_file(data, tmp_path / "other.hdf5")  # alike, but another file
    assert not same_file(data, tmp_path / "new.hdf5")  # not there yet


def test_a_block_that_wrote_nothing_leaves_the_file_as_it_was(tmp_path):
    path = tmp_path / "replay.mp4"
    path.write_bytes(b"an earlier video")
    with written_whole(path, keep_suffix=True):
        pass  # no demo selected: nothing rendered
    assert path.read_bytes() == b"an earlier video"


def test_a_folder_put_in_place_leaves_one_complete_folder_whenever_it_is_killed(tmp_path):
    """veragmil-export-lerobot --force: the export it replaces is set aside whole, never half deleted."""
    output, partial = tmp_path / "export", tmp_path / ".export.partial"
    for folder, text in ((output, "old"), (partial, "new")):
        folder.mkdir()
        (folder / "meta.json").write_text(text)
    put_folder_in_place(partial, output)
    assert (output / "meta.json").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["export"]
    # killed between its two renames: the old export set aside, the new one not yet in place
    output.rename(tmp_path / ".export.replaced")
    recover_folder(output)
    assert (output / "meta.json").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["export"]
    # killed after the new one was put in place, before the old one was deleted
    (tmp_path / ".export.replaced").mkdir()
    recover_folder(output)
    assert (output / "meta.json").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["export"]


def test_a_line_a_kill_cut_short_is_left_out_and_cut_off_before_the_next(tmp_path):
    path = tmp_path / "episodes.jsonl"
    append_line(path, '{"episode": 0}')
    with open(path, "a") as f:
        f.write('{"episode": 1, "succ')  # killed mid-write
    assert json_lines(path) == [{"episode": 0}]
    append_line(path, '{"episode": 1}')
    assert path.read_text() == '{"episode": 0}\n{"episode": 1}\n'
    assert json_lines(path) == [{"episode": 0}, {"episode": 1}]


def test_a_damaged_line_inside_a_record_is_skipped_not_fatal(tmp_path):
    path = tmp_path / "rows.jsonl"
    path.write_text('{"a": 1}\n{"a": 2{"a": 3}\n\n{"a": 4}\n')
    assert json_lines(path) == [{"a": 1}, {"a": 4}]
    empty = tmp_path / "empty.jsonl"
    append_line(empty, "{}")
    assert json_lines(empty) == [{}]
