"""Reporting evaluations: the paper's tables, stages and chart of one evaluation (tables), and what compares models
across checkpoints, training seeds, bowls and evaluations (comparisons)."""

from veragmil_suite.evaluation.reporting.comparisons import (
    SHARED_SETTINGS,
    learning_curves,
    paired_comparison,
    paired_markdown,
    pool,
    seed_markdown,
    seed_spread,
    write_learning_curves,
    write_seed_tables,
)
from veragmil_suite.evaluation.reporting.tables import (
    EvaluationResult,
    json_safe,
    summarize,
    video_name,
    wilson_interval,
)

__all__ = [
    "SHARED_SETTINGS",
    "EvaluationResult",
    "json_safe",
    "learning_curves",
    "paired_comparison",
    "paired_markdown",
    "pool",
    "seed_markdown",
    "seed_spread",
    "summarize",
    "video_name",
    "wilson_interval",
    "write_learning_curves",
    "write_seed_tables",
]
