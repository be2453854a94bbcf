"""results/awake_pile/probe_pile_up_solver.py: the solver's iterations and cost on states with the whole pile awake."""

from helpers.programs import run_script

from veragmil_suite.models.foods import DEFAULT_PHYSICS, FOODS
from veragmil_suite.models.scoop_task import pile_solver_options

SCRIPT = "results/awake_pile/probe_pile_up_solver.py"


def test_each_setting_is_solved_on_the_same_awake_states():
    out = run_script(SCRIPT, "--food", "pasta", "--every", "10").stdout
    rows = {line[:22].strip(): line[22:].split() for line in out.splitlines()[2:]}
    assert {"the task's", "iterations 100", "warm start off"} <= set(rows)
    assert len({row[-1] for row in rows.values()}) == 1  # a setting of the solver changes no contact
    task, more = float(rows["the task's"][0]), float(rows["iterations 100"][0])
    cap = int(pile_solver_options(FOODS["pasta"].grain(DEFAULT_PHYSICS), DEFAULT_PHYSICS)["iterations"])
    assert 0 < task <= cap and more >= task  # never past the task's cap (pasta's own); a higher cap never stops earlier


def test_an_unknown_food_is_refused_naming_the_accepted_ones():
    result = run_script(SCRIPT, "--food", "caviar", check=False)
    assert result.returncode == 2 and "unknown food 'caviar'; accepted foods: rice" in result.stderr
