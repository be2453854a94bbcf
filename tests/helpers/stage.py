"""
Runs one console program's main, or makes and steps an environment, in a fresh interpreter as a user's would, with
every warning of veragmil_suite's own modules shown (Python shows only some categories by default) and every log
record at WARNING or above printed: tests/test_quiet.py reads what this prints.

    python -m helpers.stage env '{"food": "pasta", ...}'
    python -m helpers.stage veragmil_suite.scripts.evaluate main --agent expert ...
"""

import importlib
import json
import logging
import sys
import warnings

warnings.filterwarnings("default", module="veragmil_suite")
logging.basicConfig(level=logging.WARNING, format="log record %(levelname)s %(name)s: %(message)s")

import veragmil_suite  # noqa: E402, F401  first, as the README says: before robosuite


def make_and_step(env_kwargs: dict, steps: int = 3) -> int:
    import numpy as np
    import robosuite

    env = robosuite.make("ScoopGranular", **env_kwargs)
    env.reset()
    for _ in range(steps):
        env.step(np.zeros(env.action_dim))
    env.close()
    return 0


if __name__ == "__main__":
    if sys.argv[1] == "env":
        sys.exit(make_and_step(json.loads(sys.argv[2])))
    module, function, *argv = sys.argv[1:]
    sys.exit(getattr(importlib.import_module(module), function)(argv))
