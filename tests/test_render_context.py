"""ScoopGranular keeps its offscreen render context across hard resets and reloaded XML while the scene's render
assets stay the same, and draws with it what a new context draws."""

import copy
import gc

import mujoco
import numpy as np
import pytest
import robosuite

from veragmil_suite.environments.render_context import same_render_assets

CAMERAS = dict(camera_names=["overhead", "agentview"], camera_heights=32, camera_widths=32, camera_depths=True)
SCENE = dict(robots="XArm7", n_grains=12, pile_variants=2, has_renderer=False, has_offscreen_renderer=True)


def _pictures(obs: dict) -> dict:
    return {k: v for k, v in obs.items() if k.endswith(("_image", "_depth"))}


def _assert_same_pictures(a: dict, b: dict) -> None:
    assert sorted(a) == sorted(b) and len(a) == 4
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_resets_and_a_reloaded_scene_keep_one_context_and_draw_what_a_new_one_draws():
    kept = robosuite.make("ScoopGranular", food="pasta", use_camera_obs=True, **SCENE, **CAMERAS)
    fresh = robosuite.make("ScoopGranular", food="pasta", use_camera_obs=True, **SCENE, **CAMERAS)
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, size=(2, kept.action_dim))
    contexts, variants = [], set()
    for seed in range(3):
        fresh._render_context = None  # a context of its own, as robosuite makes at each hard reset
        pictures = [_pictures(kept.reset(seed=seed)), _pictures(fresh.reset(seed=seed))]
        _assert_same_pictures(*pictures)
        for action in actions:
            _assert_same_pictures(_pictures(kept.step(action)[0]), _pictures(fresh.step(action)[0]))
        contexts.append(kept.sim._render_context_offscreen)  # held: no id of a freed context is reused
        variants.add(kept.pile_variant)
    assert len(variants) == 2 and all(c is contexts[0] for c in contexts)  # other piles, one context
    # robomimic's reset_to and robosuite's playback reload a recorded XML, here of another food and grain count: the
    # context goes on
    headless = {**SCENE, "n_grains": 9, "has_offscreen_renderer": False, "use_camera_obs": False}
    recorded = robosuite.make("ScoopGranular", food="rice", **headless)
    recorded.reset(seed=5)
    xml = recorded.sim.model.get_xml()
    context = kept.sim._render_context_offscreen
    kept.reset_from_xml_string(xml)
    fresh._render_context = None
    fresh.reset_from_xml_string(xml)
    assert (kept.food.name, kept.n_grains) == ("rice", 9)
    assert kept.sim._render_context_offscreen is context
    assert fresh.sim._render_context_offscreen is not context
    _assert_same_pictures(_pictures(kept._get_observations(force_update=True)), _pictures(fresh._get_observations()))
    recorded.close()
    kept.close()
    assert kept._render_context is None  # closed: nothing keeps the context alive
    fresh.close()


@pytest.fixture(scope="module")
def scene_model():
    env = robosuite.make("ScoopGranular", food="rice", use_camera_obs=False, **SCENE)
    yield env.sim.model._model
    env.close()


@pytest.mark.parametrize(
    "change",
    [
        "tex_data",
        "tex_width",
        "mesh_vert",
        "mat_texid",
        "mat_texrepeat",
        "plane size",
        "offscreen width",
        "offscreen samples",
        "fog",
        "extent",
    ],
)
def test_a_model_that_draws_otherwise_gets_a_context_of_its_own(scene_model, change):
    """Each kind of model value mjr_makeContext reads: a model that differs in one is not drawn with the context."""
    model = scene_model
    other = copy.copy(model)
    assert same_render_assets(model, other)
    planes = np.flatnonzero(other.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
    edits = {
        "tex_data": lambda: other.tex_data.__setitem__(0, other.tex_data[0] ^ 1),
        "tex_width": lambda: other.tex_width.__setitem__(0, other.tex_width[0] + 1),
        "mesh_vert": lambda: other.mesh_vert.__setitem__((0, 0), other.mesh_vert[0, 0] + 1e-3),
        "mat_texid": lambda: other.mat_texid.__setitem__((0, 1), -1 if other.mat_texid[0, 1] >= 0 else 0),
        "mat_texrepeat": lambda: other.mat_texrepeat.__setitem__((0, 0), other.mat_texrepeat[0, 0] + 1),
        "plane size": lambda: other.geom_size.__setitem__((planes[0], 0), other.geom_size[planes[0], 0] + 0.1),
        "offscreen width": lambda: setattr(other.vis.global_, "offwidth", other.vis.global_.offwidth + 1),
        "offscreen samples": lambda: setattr(other.vis.quality, "offsamples", other.vis.quality.offsamples + 2),
        "fog": lambda: other.vis.rgba.fog.__setitem__(0, 1 - other.vis.rgba.fog[0]),
        "extent": lambda: setattr(other.stat, "extent", other.stat.extent * 1.01),
    }
    edits[change]()
    assert not same_render_assets(model, other)


def test_a_context_freed_while_another_is_current_leaves_the_others_pictures_alone():
    """robosuite freed a render context, and rendered, with whatever GL context was current: an environment closed
    and collected beside another deleted the other's textures, and the other's next pictures were noise."""
    first = robosuite.make("ScoopGranular", food="pasta", use_camera_obs=True, **SCENE, **CAMERAS)
    expected = _pictures(first.reset(seed=1))
    second = robosuite.make("ScoopGranular", food="pasta", use_camera_obs=True, **SCENE, **CAMERAS)
    second.reset(seed=2)  # its context is the current one
    first.close()
    del first
    gc.collect()
    second.reset(seed=1)
    _assert_same_pictures(_pictures(second._get_observations(force_update=True)), expected)
    second.close()
