"""Our robomimic configs are robomimic's stock templates with only the settings our data needs changed; the templates of
our own algorithms are their config classes' defaults (as robomimic's generate_config_templates.py writes them)."""

import json
from pathlib import Path

import pytest
import robomimic

from veragmil_suite.learning import robomimic_compat, robomimic_obs
from veragmil_suite.learning.observation_sets import DEFAULT_OBSERVATION_SET, OBSERVATION_SETS

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs" / "json"
TEMPLATE_DIR = Path(robomimic.__file__).parent / "exps" / "templates"

# dataset path, observation keys, rollout and output settings (prefixes match whole subtrees)
ALLOWED = (
    "experiment.name",
    "experiment.rollout.",
    "experiment.render_video",
    "experiment.keep_all_videos",
    "experiment.video_skip",
    "experiment.save.",
    "train.data",
    "train.output_dir",
    "observation.modalities.obs.",
)
# recurrent policies: robomimic's BC-RNN is its BC template with the RNN switched on over a sequence
ALLOWED_RNN = ("train.seq_length", "algo.rnn.enabled", "algo.rnn.horizon")
# robomimic's paper preset of BC-RNN for human low-dim demonstrations (scripts/generate_paper_configs.py): a GMM head
# straight on the LSTM; test_the_gmm_config_is_robomimics_paper_preset_for_human_demonstrations holds these keys to
# the preset's values
PAPER_PRESET_RNN = ("algo.gmm.enabled", "algo.actor_layer_dims")
PAPER_PRESET_CONFIGS = ("bc_rnn_gmm",)
# Diffusion Policy: windows of its horizons, no next observations, DDIM instead of DDPM (configs/README.md)
ALLOWED_DIFFUSION = (
    "train.frame_stack",
    "train.seq_length",
    "train.hdf5_load_next_obs",
    "algo.ddpm.enabled",
    "algo.ddim.enabled",
)

# Diffusion Policy for a CPU: the U-Net's widths halved, a quarter of the cost a gradient step (configs/README.md);
# test_the_small_diffusion_config_differs_from_the_full_one_only_in_its_widths holds it to that
CPU_PRESET_DIFFUSION = ("algo.unet.down_dims",)
CPU_PRESET_CONFIGS = ("diffusion_policy_small",)

CONFIGS = sorted(p.stem for p in CONFIG_DIR.glob("*.json"))


def _flatten(tree, prefix=""):
    if isinstance(tree, dict) and tree:
        out = {}
        for key, value in tree.items():
            out.update(_flatten(value, f"{prefix}{key}."))
        return out
    return {prefix[:-1]: tree}


def _load(name):
    with open(CONFIG_DIR / f"{name}.json") as f:
        return json.load(f)


def _template(algo_name):
    path = TEMPLATE_DIR / f"{algo_name}.json"
    if path.exists():
        return json.loads(path.read_text())
    from robomimic.config import config_factory

    return json.loads(config_factory(algo_name).dump())


def _differences(config):
    template = _flatten(_template(config["algo_name"]))
    ours = _flatten(config)
    return {k for k in template.keys() | ours.keys() if template.get(k, KeyError) != ours.get(k, KeyError)}


def test_the_planned_configs_exist():
    assert {"bc", "bc_rnn", "bcq", "bc_rnn_image", "diffusion_policy"} <= set(CONFIGS)


@pytest.mark.parametrize("name", [n for n in CONFIGS if not _load(n)["observation"]["modalities"]["obs"]["rgb"]])
def test_low_dim_configs_observe_the_default_observation_set(name):
    low_dim = _load(name)["observation"]["modalities"]["obs"]["low_dim"]
    assert tuple(low_dim) == OBSERVATION_SETS[DEFAULT_OBSERVATION_SET]


@pytest.mark.parametrize("name", CONFIGS)
def test_config_differs_from_its_template_only_where_allowed(name):
    config = _load(name)
    allowed = ALLOWED + (ALLOWED_RNN if config["algo"].get("rnn", {}).get("enabled") else ())
    allowed += ALLOWED_DIFFUSION if config["algo_name"] == "diffusion_policy" else ()
    allowed += PAPER_PRESET_RNN if name in PAPER_PRESET_CONFIGS else ()
    allowed += CPU_PRESET_DIFFUSION if name in CPU_PRESET_CONFIGS else ()
    differences = _differences(config)
    assert differences, "a config identical to its template sets no dataset or observations"
    unexpected = sorted(
        k for k in differences if not any(k == a or (a.endswith(".") and k.startswith(a)) for a in allowed)
    )
    assert unexpected == [], f"{name}.json changes template settings it should leave alone: {unexpected}"


def test_the_small_diffusion_config_differs_from_the_full_one_only_in_its_widths():
    full, small = _flatten(_load("diffusion_policy")), _flatten(_load("diffusion_policy_small"))
    assert {k for k in full.keys() | small.keys() if full.get(k) != small.get(k)} == {
        "experiment.name",
        *CPU_PRESET_DIFFUSION,
    }
    assert small["algo.unet.down_dims"] == [w // 2 for w in full["algo.unet.down_dims"]]


def test_the_gmm_config_is_robomimics_paper_preset_for_human_demonstrations():
    from robomimic.config import config_factory
    from robomimic.scripts.generate_paper_configs import modify_bc_rnn_config_for_dataset

    preset = json.loads(modify_bc_rnn_config_for_dataset(config_factory("bc"), "lift", "ph", "low_dim").dump())
    ours = _load("bc_rnn_gmm")
    assert _flatten(ours["algo"]) == _flatten(preset["algo"])
    assert ours["train"]["seq_length"] == preset["train"]["seq_length"]
    assert set(_differences(ours)) - set(_differences(_load("bc_rnn"))) == set(PAPER_PRESET_RNN)


def test_the_check_catches_a_changed_hyperparameter():
    config = _load("bc")
    config["algo"]["actor_layer_dims"] = [64]
    config["train"]["batch_size"] = 7
    assert {"algo.actor_layer_dims", "train.batch_size"} <= _differences(config)


@pytest.mark.parametrize("name", CONFIGS)
def test_config_loads_into_robomimic(name):
    from robomimic.config import config_factory

    ours = _load(name)
    config = config_factory(ours["algo_name"])
    with config.values_unlocked():
        config.update(ours)  # robomimic raises on a key its config does not define
    if config.algo_name == "bc" and config.algo.rnn.enabled:
        assert config.train.seq_length == config.algo.rnn.horizon > 1
    if config.algo_name == "diffusion_policy":
        horizon = config.algo.horizon
        assert config.train.frame_stack == horizon.observation_horizon
        assert config.train.frame_stack - 1 + config.train.seq_length == horizon.prediction_horizon
    assert config.experiment.rollout.horizon == 400  # 20 s at 20 Hz, longer than the paper's 14-19 s demos


def test_observation_keys_are_what_scoopgranular_gives():
    import robosuite

    robomimic_compat.install()
    env = robosuite.make(
        "ScoopGranular",
        robots="XArm7",
        food="pasta",
        n_grains=8,
        pile_variants=1,
        has_renderer=False,
        has_offscreen_renderer=True,
        use_camera_obs=True,
        camera_names=["overhead"],
        camera_depths=True,
    )
    obs = robomimic_obs.observation(env, env.reset())
    env.close()
    for name in CONFIGS:
        modalities = _load(name)["observation"]["modalities"]["obs"]
        used = [k for keys in modalities.values() for k in keys]
        assert used and set(used) <= set(obs), f"{name}.json uses keys ScoopGranular lacks: {set(used) - set(obs)}"
    assert obs["overhead_image"].shape == (84, 84, 3) and obs["overhead_depth"].shape == (84, 84, 1)
    assert obs["desired_pose"].shape == (7,)


def test_every_registered_algorithm_has_its_config_and_a_name_registers_once():
    from veragmil_suite.learning.algorithms import ALGORITHMS, StudyAlgorithm, register_algorithm

    assert {"bc", "bc_rnn", "bcq", "diffusion_policy"} <= set(ALGORITHMS)
    for algorithm in ALGORITHMS.values():
        config = json.loads((CONFIG_DIR / f"{algorithm.config}.json").read_text())
        # a variant trains the robomimic algorithm its name begins with: BC-RNN robomimic's bc with its RNN on,
        # diffusion_policy_small our diffusion_policy with a narrower U-Net
        assert algorithm.name.startswith(config["algo_name"]), (algorithm.name, config["algo_name"])
    with pytest.raises(ValueError, match="registered already"):
        register_algorithm(StudyAlgorithm("bc", "bc", "BC again"))
