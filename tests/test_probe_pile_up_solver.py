"""results/awake_pile/probe_pile_up_solver.py: the solver's iterations and cost on states with the whole pile awake."""

import runpy
from pathlib import Path

import pytest

from veragmil_suite.models.foods import DEFAULT_PHYSICS
from veragmil_suite.models.scoop_task import PHYSICS_SOLVER_OPTIONS

SCRIPT = Path(__file__).parents[1] / "results" / "awake_pile" / "probe_pile_up_solver.py"


@pytest.fixture(scope="module")
def probe():
    return runpy.run_path(str(SCRIPT), run_name="probe_pile_up_solver")


def test_each_setting_is_solved_on_the_same_awake_states(probe, capsys):
    probe["main"](["--food", "pasta", "--every", "10"])
    out = capsys.readouterr().out
    rows = {line[:22].strip(): line[22:].split() for line in out.splitlines()[2:]}
    assert list(rows) == list(probe["VARIANTS"])
    assert len({row[-1] for row in rows.values()}) == 1  # a setting of the solver changes no contact
    task, more = float(rows["the task's"][0]), float(rows["iterations 100"][0])
    cap = int(PHYSICS_SOLVER_OPTIONS[DEFAULT_PHYSICS]["iterations"])
    assert 0 < task <= cap and more >= task  # never past the task's cap; a higher cap never stops earlier


def test_an_unknown_food_is_refused_naming_the_accepted_ones(probe, capsys):
    with pytest.raises(SystemExit):
        probe["main"](["--food", "caviar"])
    assert "unknown food 'caviar'; accepted foods: rice" in capsys.readouterr().err
