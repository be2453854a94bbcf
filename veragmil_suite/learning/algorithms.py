"""The algorithms a study trains, registered by name: each one's robomimic config (configs/json) and its column
name in the tables. The paper's three and our Diffusion Policy (veragmil_suite.learning.algos) are registered here;
another robomimic algorithm joins the grid with a function decorated by register_algorithm."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from veragmil_suite.learning.checkpoints import config_rnn_horizon
from veragmil_suite.utils.asset_paths import config_path
from veragmil_suite.utils.registry import Registry


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

    def stock_config(self) -> dict:
        """Its robomimic config as configs/json holds it."""
        return json.loads(Path(config_path(self.config)).read_text())

    @property
    def recurrent(self) -> bool:
        """Whether its policy keeps a hidden state through a rollout (its config's ``algo.rnn.enabled``)."""
        return config_rnn_horizon(self.stock_config()) is not None


ALGORITHMS: Registry[StudyAlgorithm] = Registry("algorithm", StudyAlgorithm)
register_algorithm = ALGORITHMS.register


@register_algorithm
def bc() -> StudyAlgorithm:
    """robomimic's BC: an MLP from observations to actions."""
    return StudyAlgorithm("bc", "bc", "BC")


@register_algorithm
def bc_rnn() -> StudyAlgorithm:
    """robomimic's BC with its LSTM on, trained on sequences."""
    return StudyAlgorithm("bc_rnn", "bc_rnn", "BC-RNN")


@register_algorithm
def bc_rnn_gmm() -> StudyAlgorithm:
    """robomimic's paper preset of BC-RNN for human demonstrations: a 5-mode GMM head straight on the LSTM."""
    return StudyAlgorithm("bc_rnn_gmm", "bc_rnn_gmm", "BC-RNN GMM")


@register_algorithm
def bcq() -> StudyAlgorithm:
    """robomimic's BCQ: batch-constrained Q-learning on the demos' rewards."""
    return StudyAlgorithm("bcq", "bcq", "BCQ")


@register_algorithm
def diffusion_policy() -> StudyAlgorithm:
    """Diffusion Policy (veragmil_suite.learning.algos), a robomimic algorithm of ours."""
    return StudyAlgorithm("diffusion_policy", "diffusion_policy", "Diffusion Policy")


@register_algorithm
def diffusion_policy_small() -> StudyAlgorithm:
    """Diffusion Policy with its U-Net's widths halved (128-256-512, 18M weights against 66M): a gradient step costs
    a quarter as much on a CPU (configs/README.md), so that a training run fits a working session there."""
    return StudyAlgorithm("diffusion_policy_small", "diffusion_policy_small", "Diffusion Policy small U-Net")
