"""
ScoopGranular's offscreen render context, kept across hard resets and reloaded XML while the scene's render assets
stay the same.

robosuite builds a new MjSim at every hard reset (every episode) and every ``reset_from_xml_string`` (robomimic's
``reset_to``, playback), and with it a new MjRenderContextOffscreen: an OSMesa GL context and a MuJoCo mjrContext.
Uploading the arena's textures into that mjrContext took 0.4 s of the 0.66 s a reset of an environment with a camera
took here (0.09 s without one). The mjrContext holds only what ``mjr_makeContext`` reads from the model (textures,
materials' texture settings, meshes, height fields, skins, planes' grids, the offscreen buffer and the visual
settings; MuJoCo 3.8.1's src/render/classic/render_context.c); when the new model's are equal to the context's model's,
the same context draws the new scene as a fresh one would, pixel for pixel, and the new simulation takes it with a
scene (mjvScene), camera and options of its own.

A longer-lived context meets a robosuite defect more often: MjRenderContext frees its MuJoCo context, and renders,
with whatever GL context is current, and GL object ids are counted per context, so a context that the garbage
collector freed while another was current deleted that other's textures and framebuffer, whose next pictures were
noise (two environments with cameras, one closed). ``draw_on_own_gl_context`` makes every context current before it
renders, reads or frees.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from robosuite.utils.binding_utils import MjRenderContext

if TYPE_CHECKING:
    from robosuite.utils.binding_utils import MjSim

# the model's arrays mjr_makeContext reads (MuJoCo 3.8.1): textures, the materials' texture settings, meshes,
# height fields and skins
RENDER_ASSET_ARRAYS = (
    *("tex_type", "tex_colorspace", "tex_height", "tex_width", "tex_nchannel", "tex_adr", "tex_data"),
    *("mat_texid", "mat_texuniform", "mat_texrepeat"),
    *("mesh_vertadr", "mesh_vertnum", "mesh_normaladr", "mesh_texcoordadr", "mesh_faceadr", "mesh_facenum"),
    *("mesh_graphadr", "mesh_vert", "mesh_normal", "mesh_texcoord", "mesh_face", "mesh_facenormal"),
    *("mesh_facetexcoord", "mesh_graph"),
    *("hfield_size", "hfield_nrow", "hfield_ncol", "hfield_adr", "hfield_data"),
    *("skin_vertnum", "skin_texcoordadr", "skin_faceadr", "skin_facenum", "skin_face", "skin_texcoord"),
)
# the visual settings it reads, by group of mjVisual (every setting of these groups is compared)
RENDER_VISUAL_GROUPS = ("global_", "quality", "map", "rgba")
# robosuite's MjRenderContext scene size
SCENE_MAX_GEOMS = 10000


def render_assets(model: mujoco.MjModel) -> list[tuple[str, object]]:
    """What an mjrContext made for ``model`` holds of it, as (name, value) pairs to compare."""
    values = [(name, getattr(model, name)) for name in RENDER_ASSET_ARRAYS]
    planes = model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE
    values += [("plane geom_size", model.geom_size[planes]), ("plane geom_matid", model.geom_matid[planes])]
    values.append(("stat.extent", np.float64(model.stat.extent)))
    for group in RENDER_VISUAL_GROUPS:
        settings = getattr(model.vis, group)
        for name in sorted(n for n in dir(settings) if not n.startswith("_")):
            value = getattr(settings, name)
            if not callable(value):
                values.append((f"vis.{group}.{name}", np.asarray(value)))
    return values


def same_render_assets(a: mujoco.MjModel, b: mujoco.MjModel) -> bool:
    """Whether an mjrContext made for ``a`` draws ``b``'s scenes as one made for ``b`` would."""
    return all(
        name_a == name_b and va.shape == vb.shape and va.dtype == vb.dtype and np.array_equal(va, vb)
        for (name_a, va), (name_b, vb) in zip(render_assets(a), render_assets(b), strict=True)
    )


def adopt_render_context(sim: MjSim, context: MjRenderContext) -> None:
    """
    Makes ``context`` (made for a model whose render assets are ``sim``'s, same_render_assets) ``sim``'s offscreen
    render context: current, as a new one is, with a scene, camera, options and perturbation of ``sim``'s model as
    robosuite's MjRenderContext makes them.
    """
    context.gl_ctx.make_current()
    context.sim, context.model, context.data = sim, sim.model, sim.data
    context.scn = mujoco.MjvScene(sim.model._model, maxgeom=SCENE_MAX_GEOMS)
    context.cam = mujoco.MjvCamera()
    context.cam.fixedcamid = 0
    context.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
    context.vopt = mujoco.MjvOption()
    context.pert = mujoco.MjvPerturb()
    context.pert.active = 0
    context.pert.select = 0
    context.pert.skinselect = -1
    sim.add_render_context(context)


def draw_on_own_gl_context() -> None:
    """Makes robosuite's MjRenderContext render, read pixels and free its MuJoCo context with its own GL context
    current (making one current took 4 us against 14 ms for an 84x84 picture here); idempotent."""
    for name in ("render", "read_pixels", "__del__"):
        method = getattr(MjRenderContext, name)
        if not getattr(method, "_on_own_gl_context", False):
            setattr(MjRenderContext, name, _on_own_gl_context(method))


def _on_own_gl_context(method):
    @functools.wraps(method)
    def on_own_gl_context(self, *args, **kwargs):
        gl_ctx = getattr(self, "gl_ctx", None)  # absent when __init__ failed before making it
        if gl_ctx is not None:
            gl_ctx.make_current()
        return method(self, *args, **kwargs)

    on_own_gl_context._on_own_gl_context = True
    return on_own_gl_context


draw_on_own_gl_context()


class RenderContextMixin:
    """Keeps the environment's offscreen render context for the next simulation whose render assets are the same."""

    _render_context: MjRenderContext | None = None
    _reloading_xml: bool = False

    def _keep_render_context(self) -> None:
        """Hands the kept render context to a new simulation that draws the same (after MujocoEnv._initialize_sim)."""
        kept, self._render_context = self._render_context, None
        if kept is not None and self.has_offscreen_renderer and self.sim._render_context_offscreen is None:
            if same_render_assets(kept.model._model, self.sim.model._model):
                adopt_render_context(self.sim, kept)

    def _remember_render_context(self) -> None:
        """Remembers the simulation's render context (after MujocoEnv._reset_internal made or adopted it)."""
        if self.has_offscreen_renderer:
            self._render_context = self.sim._render_context_offscreen

    def reset_from_xml_string(self, xml_string: str) -> None:
        """robosuite's reset_from_xml_string, whose close() keeps the render context for the reloaded scene."""
        self._reloading_xml = True
        try:
            super().reset_from_xml_string(xml_string)
        finally:
            self._reloading_xml = False

    def close(self) -> None:
        """robosuite's close, which lets the render context go too (unless a reloaded XML takes it)."""
        super().close()
        if not self._reloading_xml:
            self._render_context = None
