"""benchmarks/bench_against.py: whole expert episodes of this checkout against another, each side in its own process."""

import runpy
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def bench_against():
    return runpy.run_path(str(ROOT / "benchmarks" / "bench_against.py"), run_name="bench_against")


def test_both_sides_run_their_own_checkout_and_the_ratio_is_printed(bench_against, tmp_path, capsys):
    """The base side is a copy of the package (what git archive gives): it must import from there, not from the
    installed checkout, and each side's episodes are counted."""
    base = tmp_path / "base"
    for folder in ("veragmil_suite", "models", "configs"):
        shutil.copytree(ROOT / folder, base / folder, ignore=shutil.ignore_patterns("__pycache__", "checkpoints"))
    args = ["--base", str(base), "--food", "pasta", "--episodes", "1", "--rounds", "1", "--lift-steps", "5"]
    bench_against["main"]([*args, "--sleep", "off", "--cache-root", str(tmp_path / "cache")])
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if line.startswith("1 ")]
    assert [row[1] for row in rows] == ["base", "this"]
    assert all(row[-1] in ("0/1", "1/1") for row in rows), out  # each side's one episode is counted
    assert "pasta, whole expert episodes, this / base: " in out


def test_a_base_without_the_package_is_refused_by_name(bench_against, tmp_path, capsys):
    with pytest.raises(SystemExit):
        bench_against["main"](["--base", str(tmp_path)])
    assert f"--base {tmp_path} holds no veragmil_suite package" in capsys.readouterr().err


def test_an_unknown_food_is_refused_naming_the_accepted_ones(bench_against, capsys):
    with pytest.raises(SystemExit):
        bench_against["main"](["--base", str(ROOT), "--food", "caviar"])
    assert "unknown food 'caviar'; accepted foods: rice" in capsys.readouterr().err
