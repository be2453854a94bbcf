"""
The one robosuite log record that this project filters: robosuite's own settings quiet the rest
(veragmil_suite.private_macros).

robosuite 1.5.2's wheel leaves out its ``robosuite.examples`` package, so every import of robosuite, in every
process, warns that the mink whole-body IK (a controller of the GR1 humanoid's) cannot be loaded: a fact about
robosuite's packaging, not about this process. :func:`drop_missing_examples_warning` filters that record alone from
robosuite's logger, and must run before robosuite is imported: importing veragmil_suite first does.
"""

from __future__ import annotations

import logging

ROBOSUITE_LOGGER = "robosuite_logs"  # robosuite.utils.log_utils.DefaultLogger's name
MISSING_EXAMPLES_WARNING = "Could not load the mink-based whole-body IK"


class _MissingExamplesFilter(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith(MISSING_EXAMPLES_WARNING)


def drop_missing_examples_warning() -> None:
    """Filters robosuite's warning about its absent examples package from robosuite's logger (idempotent)."""
    logger = logging.getLogger(ROBOSUITE_LOGGER)
    if not any(isinstance(f, _MissingExamplesFilter) for f in logger.filters):
        logger.addFilter(_MissingExamplesFilter())
