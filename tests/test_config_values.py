"""A robomimic config's values are checked before training: the kind of robomimic's default for each key, and the
ranges of the counts a training needs."""

import json
from pathlib import Path

import pytest

from veragmil_suite.learning import robomimic_compat
from veragmil_suite.learning.config_values import BOUNDS, leaves, value_problem

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs" / "json"


def _defaults(algo):
    robomimic_compat.install()
    from robomimic.config import config_factory

    return config_factory(algo).to_dict()


@pytest.mark.parametrize("path", sorted(CONFIG_DIR.glob("*.json")), ids=lambda p: p.stem)
def test_every_shipped_config_holds_values_robomimic_trains_with(path):
    config = json.loads(path.read_text())
    assert value_problem(config, _defaults(config["algo_name"])) is None


@pytest.mark.parametrize(
    "train,message",
    [
        ({"num_epochs": -3}, "train.num_epochs is -3: it must be a whole number of at least 1"),
        ({"num_epochs": 0}, "train.num_epochs is 0"),
        ({"num_epochs": None}, "train.num_epochs is None"),
        ({"num_epochs": 2.5}, "train.num_epochs is 2.5"),
        ({"batch_size": True}, "train.batch_size is True"),
        ({"batch_size": "abc"}, "train.batch_size is 'abc'"),
        ({"seq_length": 0}, "train.seq_length is 0"),
        ({"frame_stack": -1}, "train.frame_stack is -1"),
        ({"num_data_workers": -1}, "train.num_data_workers is -1: it must be a whole number of at least 0"),
        ({"hdf5_normalize_obs": 1}, "train.hdf5_normalize_obs is 1: it must be true or false"),
        ({"hdf5_cache_mode": 3}, "train.hdf5_cache_mode is 3: it must be a string"),
        ({"data": 5}, "train.data is 5: it must be a string or null"),
        ({"seed": 2**32}, "train.seed is 4294967296: it must be a whole number of at least 0 and at most 4294967295"),
    ],
)
def test_a_value_robomimic_cannot_train_with_is_named_with_what_its_key_accepts(train, message):
    problem = value_problem({"algo_name": "bc", "train": train}, _defaults("bc"))
    assert problem is not None and problem.startswith(message), problem


@pytest.mark.parametrize(
    "config,message",
    [
        ({"algo": {"optim_params": {"policy": {"learning_rate": {"initial": 0}}}}},
         "algo.optim_params.policy.learning_rate.initial is 0: it must be a finite number above 0"),
        ({"algo": {"optim_params": {"critic": {"learning_rate": {"initial": -1e-3}}}}},
         "algo.optim_params.critic.learning_rate.initial is -0.001"),
        ({"algo": {"actor": {"layer_dims": 300}}}, "algo.actor.layer_dims is 300: it must be a list"),
        ({"algo": {"discount": "high"}}, "algo.discount is 'high': it must be a finite number"),
        ({"experiment": {"epoch_every_n_steps": 0}}, "experiment.epoch_every_n_steps is 0"),
        ({"experiment": {"rollout": {"horizon": -1}}}, "experiment.rollout.horizon is -1"),
    ],
)  # fmt: skip
def test_nested_values_are_checked_too(config, message):
    problem = value_problem({"algo_name": "bcq", **config}, _defaults("bcq"))
    assert problem is not None and problem.startswith(message), problem


def test_null_stands_where_robomimic_reads_it_as_off_and_numbers_stand_for_reals():
    config = {
        "algo_name": "bc",
        "experiment": {"epoch_every_n_steps": None, "save": {"every_n_epochs": None}},
        "train": {"hdf5_cache_mode": None, "hdf5_filter_key": "train"},
        "algo": {"optim_params": {"policy": {"learning_rate": {"initial": 1}}}, "loss": {"l2_weight": 2}},
    }
    assert value_problem(config, _defaults("bc")) is None


def test_the_diffusion_policy_horizons_are_counts():
    problem = value_problem({"algo_name": "diffusion_policy", "algo": {"horizon": {"action_horizon": 0}}},
                            _defaults("diffusion_policy"))  # fmt: skip
    assert problem is not None and problem.startswith("algo.horizon.action_horizon is 0"), problem


def test_every_bound_names_keys_robomimic_has():
    import fnmatch

    robomimic_compat.install()
    from robomimic.config.base_config import REGISTERED_CONFIGS

    keys = {name for algo in REGISTERED_CONFIGS for name, _ in leaves(_defaults(algo))}
    for pattern in BOUNDS:
        assert any(fnmatch.fnmatchcase(k, pattern) for k in keys), pattern
