"""expert_probe.py on a calibrated grain model with some fields changed, e.g.

    python results/calibration/exploration/probe_with_grain_changes.py buckwheat \
        '{"torsional_friction_m": 2e-4, "rolling_friction_m": 1e-4}' 0,1,2,3
"""

import json
import runpy
import sys
from dataclasses import replace
from pathlib import Path

import veragmil_suite  # noqa
from veragmil_suite.models import foods

food = sys.argv[1]
changes = json.loads(sys.argv[2])
spec = foods.FOODS[food]
foods.FOODS[food] = replace(spec, calibrated=replace(spec.calibrated, **changes))
sys.argv = ["expert_probe.py", food, "calibrated", sys.argv[3]]
runpy.run_path(str(Path(__file__).with_name("expert_probe.py")), run_name="__main__")
