"""The algorithms a study trains, registered by name: each one's robomimic config (configs/json) and its column
name in the tables. The paper's three and our Diffusion Policy (veragmil_suite.learning.algos) are registered here;
another robomimic algorithm joins the grid with one register_algorithm call."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StudyAlgorithm:
    """One algorithm of the grid.

    Attributes:
        name: the name veragmil-study --algos takes (BC-RNN is robomimic's bc with its RNN on).
        config: the robomimic config it trains with, configs/json/<config>.json (low-dim observations).
        label: its name in Tables II and III and in every model's column.
    """

    name: str
    config: str
    label: str


ALGORITHMS: dict[str, StudyAlgorithm] = {}


def register_algorithm(name: str, config: str, label: str) -> StudyAlgorithm:
    """Adds an algorithm to the grid (a name registered twice is refused)."""
    if name in ALGORITHMS:
        raise ValueError(f"algorithm {name!r} is registered already")
    ALGORITHMS[name] = StudyAlgorithm(name, config, label)
    return ALGORITHMS[name]


register_algorithm("bc", "bc", "BC")
register_algorithm("bc_rnn", "bc_rnn", "BC-RNN")
# robomimic's paper preset of BC-RNN for human demonstrations: a 5-mode GMM head straight on the LSTM
register_algorithm("bc_rnn_gmm", "bc_rnn_gmm", "BC-RNN GMM")
register_algorithm("bcq", "bcq", "BCQ")
register_algorithm("diffusion_policy", "diffusion_policy", "Diffusion Policy")
