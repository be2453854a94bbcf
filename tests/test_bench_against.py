"""benchmarks/bench_against.py: whole expert episodes of this checkout against another, each side in its own process."""

import shutil

from helpers.programs import ROOT, run_script

SCRIPT = "benchmarks/bench_against.py"


def test_both_sides_run_their_own_checkout_and_the_ratio_is_printed(tmp_path):
    """The base side is a copy of the package (what git archive gives): it must import from there, not from the
    installed checkout, and each side's episodes are counted."""
    base = tmp_path / "base"
    for folder in ("veragmil_suite", "models", "configs"):
        shutil.copytree(ROOT / folder, base / folder, ignore=shutil.ignore_patterns("__pycache__", "checkpoints"))
    args = ["--base", str(base), "--food", "pasta", "--n-grains", "12", "--episodes", "1", "--rounds", "1"]
    args += ["--lift-steps", "5"]
    out = run_script(SCRIPT, *args, "--sleep", "off", "--cache-root", tmp_path / "cache").stdout
    rows = [line.split() for line in out.splitlines() if line.startswith("1 ")]
    assert [row[1] for row in rows] == ["base", "this"]
    assert all(row[-1] in ("0/1", "1/1") for row in rows), out  # each side's one episode is counted
    assert "pasta, whole expert episodes, this / base: " in out
