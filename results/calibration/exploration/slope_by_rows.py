"""One calibrated grain on an 8 degree plane (calibration.slope), with and without rolling and torsional friction rows.

python results/calibration/exploration/slope_by_rows.py
"""

from dataclasses import replace

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration.slope import slope_travel_m
from veragmil_suite.models import foods

CASES = [
    ("rice", {}),
    ("rice", {"rolling_friction_m": 0}),
    ("rice", {"rolling_friction_m": 0, "torsional_friction_m": 0}),
    ("buckwheat", {"rolling_friction_m": 5e-4, "torsional_friction_m": 1e-3}),
    ("buckwheat", {}),
    ("barley", {}),
    ("barley", {"rolling_friction_m": 0}),
    ("pasta", {}),
    ("pasta", {"rolling_friction_m": 0}),
]
for food, changes in CASES:
    spec = foods.FOODS[food]
    grain = replace(spec.calibrated, **changes)
    travel = slope_travel_m(replace(spec, calibrated=grain), "calibrated", 8.0)
    print(f"{food:<10} condim {grain.condim} {changes or 'catalog'}: {1000 * travel:.3f} mm in 2 s", flush=True)
