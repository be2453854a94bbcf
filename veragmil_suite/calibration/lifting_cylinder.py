"""The lifting-cylinder test: fill a tube with grains, lift it slowly, measure the heap left behind.

The standard static angle-of-repose test for granular food. Grains are built exactly as the task builds them
(GrainPile: the food catalog's grain model, mass properties and contact) and run under the task's solver settings;
only the container differs. The fill before lifting also gives the poured pile's packing fraction and bulk density;
a tall fill is poured in slabs from just above the grains already in the tube, as grains are poured from a scoop.

Angles are measured two ways on the heap's surface profile (the highest grain top in rings about the axis): the
height over the base radius, and a least-squares slope of the profile's flank (between 20% and 85% of the height).
The heap is measured when every grain has slowed under the rest speed; it is then watched a while longer, and the
rate at which its top sinks is its creep (MuJoCo's soft friction lets a loaded contact slip slowly: a heap that
creeps keeps flattening while no grain is fast).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from veragmil_suite.calibration.scene import calibration_scene, run_until_rest
from veragmil_suite.models import contact_groups
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import FoodSpec
from veragmil_suite.models.grains import GrainPile

LIFT_SPEED_M_S = 0.02
CREEP_WATCH_S = 1.0  # how long a heap at rest is watched for creep
TUBE_STAVES = 24
STAVE_HALF_THICKNESS_M = 0.005


@dataclass
class CylinderResult:
    """What one lifting-cylinder run measured."""

    n_grains: int
    grain_mass_mg: float
    fill_height_m: float
    packing_fraction: float
    bulk_density_g_cm3: float
    heap_height_m: float
    heap_radius_m: float
    angle_height_base_deg: float
    angle_slope_fit_deg: float
    heap_creep_mm_s: float  # how fast the heap's top sank over CREEP_WATCH_S after it came to rest
    settled: bool
    escaped_fast: int  # grains seen faster than EJECTED_SPEED_M_S: a solver that throws grains
    sim_time_s: float

    def as_dict(self) -> dict:
        return asdict(self)


TUBE_RADIUS_M = 0.021  # the standard test's tube, 3.5 cm filled: rice
TUBE_GRAINS_ACROSS = 3.0  # larger grains start from a tube this many grain lengths in radius...
TUBE_GRAINS = 1000  # ...which is then widened or narrowed until it holds the standard test's 1,000 grains...
TUBE_RADIUS_MAX_M = 0.06  # ...up to this (pasta: a 12 cm tube holds 718 pieces of 2-3.5 cm)
FILL_PACKING_GUESS = 0.6
# A lattice taller than this is poured in slabs this tall, each from just above the fill, so no grain lands faster
# than about 2 m/s: a thin flake falling faster crosses a layer of flakes, or the support, within one step. Rice's,
# buckwheat's and peas' standard lattices are lower and fall at once; flakes' and pasta's stand metres high.
POUR_HEIGHT_M = 0.25
POUR_SLAB_S = 1.0  # simulated time a slab is given to land before the next is poured


def tube_size(food: FoodSpec, physics: str, scale: float = 1.0) -> tuple[float, float, int]:
    """Tube radius and fill height (m) and the grains that fill it: the standard test's proportions (2.1 cm by 3.5
    cm), sized to hold its 1,000 grains (at most TUBE_RADIUS_MAX_M), all times ``scale``.

    A heap is measured in grains: peas in the rice tube (241) heap three peas high, and their height over base
    scattered 12.5-20.9 degrees over four fills against 14.7-17.0 over sixteen in a tube of 1,000
    (results/calibration/RUN.md).
    """
    grain = food.grain(physics)
    radius = min(max(TUBE_RADIUS_M, TUBE_GRAINS_ACROSS * grain.size_range_m[1]), TUBE_RADIUS_MAX_M)

    def grains(r: float) -> float:
        return math.pi * r**2 * (r * 3.5 / 2.1) * FILL_PACKING_GUESS / grain.piece_volume_m3()

    factor = min((TUBE_GRAINS / grains(radius)) ** (1 / 3), TUBE_RADIUS_MAX_M / radius)
    radius *= factor * scale
    return radius, radius * 3.5 / 2.1, max(20, int(grains(radius)))


def _model_xml(
    pile: GrainPile, radius: float, height: float, physics: str, solver_options: dict | None, poured: bool = False
) -> str:
    root, world = calibration_scene("lifting_cylinder", physics, solver_options, grain=pile.grain)
    tube = ET.SubElement(world, "body", name="tube", mocap="true", pos="0 0 0")
    t = STAVE_HALF_THICKNESS_M
    chord = 2 * (radius + t) * math.tan(math.pi / TUBE_STAVES) * 1.1
    for k in range(TUBE_STAVES):
        theta = 2 * math.pi * k / TUBE_STAVES
        stave = ET.SubElement(tube, "geom", type="box", size=f"{t} {chord / 2} {height / 2}")
        stave.set("pos", f"{(radius + t) * math.cos(theta)} {(radius + t) * math.sin(theta)} {height / 2 + 5e-4}")
        stave.set("euler", f"0 0 {theta}")
        stave.set("friction", "0.01 0 0")  # a smooth tube wall
        for key, value in contact_groups.SHELL.items():
            stave.set(key, str(value))
    for body in pile.bodies():
        if poured:  # every grain floats until its slab is poured (see _pour)
            body.set("gravcomp", "1")
        world.append(body)
    return ET.tostring(root, encoding="unicode")


@dataclass
class TubeFill:
    """The tube filled and settled: the model and state the lift starts from, and the fill's own measure."""

    model: mujoco.MjModel
    data: mujoco.MjData
    pile: GrainPile
    ids: np.ndarray  # the grains' body ids
    radius_m: float
    tube_height_m: float  # the tube is as tall as the grains' starting stack
    fill_height_m: float
    rested: bool
    escaped_fast: int

    @property
    def bulk_volume_m3(self) -> float:
        return math.pi * self.radius_m**2 * self.fill_height_m

    @property
    def packing_fraction(self) -> float:
        return float(self.pile.volumes_m3.sum() / self.bulk_volume_m3)

    @property
    def bulk_density_g_cm3(self) -> float:
        return float(self.model.body_mass[self.ids].sum() / self.bulk_volume_m3 / 1000.0)


def fill_tube(
    food: FoodSpec,
    physics: str,
    scale: float = 1.0,
    seed: int = 0,
    solver_options: dict | None = None,
    max_settle_s: float = 8.0,
) -> TubeFill:
    """The test's first half: the tube of ``scale`` times the standard size filled with ``food`` built with
    ``physics`` and settled (the poured pile's packing and bulk density)."""
    radius, _, n = tube_size(food, physics, scale)
    pile = GrainPile(food, n, np.random.default_rng(seed), physics=physics)
    shape = DishShape(
        rim_semi_axes=(radius, radius),
        floor_semi_axes=(radius, radius),
        depth=10.0,
        wall_half_thickness=STAVE_HALF_THICKNESS_M,
        floor_half_thickness=0.01,
    )
    lattice = pile.lattice_qpos(shape, rim_center=np.array([0.0, 0.0, 10.0]))
    poured = lattice[:, 2].max() > POUR_HEIGHT_M
    # the tube holds the whole lattice, poured or not (long pasta stacks a metre high)
    tube_height = float(lattice[:, 2].max() + pile.radii.max()) + 0.02
    model = mujoco.MjModel.from_xml_string(_model_xml(pile, radius, tube_height, physics, solver_options, poured))
    data = mujoco.MjData(model)
    adr = np.array([model.joint(j).qposadr[0] for j in pile.joint_names])
    data.qpos[adr[:, None] + np.arange(7)] = lattice
    ids = np.array([model.body(b).id for b in pile.body_names])
    if poured:
        rested, fast = _pour(model, data, pile, ids, adr, max_settle_s)
    else:
        rested, fast = run_until_rest(model, data, ids, max_settle_s)
    fill_height = _fill_height(data.xpos[ids], pile.thickness_radii, radius, 2 * float(pile.radii.mean()))
    return TubeFill(model, data, pile, ids, radius, tube_height, fill_height, rested, fast)


def _pour(
    model: mujoco.MjModel, data: mujoco.MjData, pile: GrainPile, ids: np.ndarray, adr: np.ndarray, max_settle_s: float
) -> tuple[bool, int]:
    """Pours a lattice taller than POUR_HEIGHT_M in slabs: each slab is lowered to just above the fill and let fall,
    the grains above it floating where they are (gravity compensated) until their turn. Returns run_until_rest's
    (came to rest, most grains seen fast) for the whole pour."""
    z = data.qpos[adr + 2].copy()
    gap = 2 * float(pile.thickness_radii.max())
    fast = 0
    waiting = np.ones(len(ids), dtype=bool)
    while True:
        landed = ~waiting
        if landed.any():  # the rest of the lattice comes down to just above the fill
            top = float((data.xpos[ids[landed], 2] + pile.radii[landed]).max()) + gap
            drop = float(z[waiting].min()) - top
            data.qpos[adr[waiting] + 2] -= drop
            z[waiting] -= drop
        else:
            top = 0.0
        slab = waiting & (z < top + POUR_HEIGHT_M)
        waiting &= ~slab
        model.body_gravcomp[ids[slab]] = 0.0
        if not waiting.any():
            rested, last = run_until_rest(model, data, ids, max_settle_s)
            return rested, max(fast, last)
        _, seen = run_until_rest(model, data, ids[~waiting], POUR_SLAB_S)
        fast = max(fast, seen)


def lifting_cylinder(
    food: FoodSpec,
    physics: str,
    scale: float = 1.0,
    seed: int = 0,
    solver_options: dict | None = None,
    max_settle_s: float = 8.0,
) -> CylinderResult:
    """Runs the test for ``food`` built with ``physics`` (its grain model and solver settings) in a tube of
    ``scale`` times the standard size.

    Sleeping stays off: a grain asleep in the tube would not notice the wall leave.
    """
    fill = fill_tube(food, physics, scale, seed, solver_options, max_settle_s)
    model, data, pile, ids = fill.model, fill.data, fill.pile, fill.ids
    half_thickness = pile.thickness_radii

    lift_to = fill.fill_height_m + 0.02
    while data.mocap_pos[0, 2] < lift_to:
        data.mocap_pos[0, 2] += LIFT_SPEED_M_S * model.opt.timestep
        mujoco.mj_step(model, data)
    data.mocap_pos[0, 2] = 5.0  # out of the way
    rest_heap, fast_heap = run_until_rest(model, data, ids, max_settle_s)
    ring = 2 * float(pile.radii.mean())
    height, base, angle_hb, angle_fit = heap_angles(data.xpos[ids], half_thickness, ring_width=ring)
    watch_from = data.time
    while data.time - watch_from < CREEP_WATCH_S:
        mujoco.mj_step(model, data, nstep=24)
    height_after = heap_angles(data.xpos[ids], half_thickness, ring_width=ring)[0]
    return CylinderResult(
        n_grains=len(ids),
        grain_mass_mg=float(model.body_mass[ids].mean() * 1e6),
        fill_height_m=fill.fill_height_m,
        packing_fraction=fill.packing_fraction,
        bulk_density_g_cm3=fill.bulk_density_g_cm3,
        heap_height_m=height,
        heap_radius_m=base,
        angle_height_base_deg=angle_hb,
        angle_slope_fit_deg=angle_fit,
        heap_creep_mm_s=(height - height_after) * 1000.0 / (data.time - watch_from),
        settled=fill.rested and rest_heap,
        escaped_fast=max(fill.escaped_fast, fast_heap),
        sim_time_s=float(data.time),
    )


def _fill_height(pos: np.ndarray, half_thickness: np.ndarray, radius: float, cell: float) -> float:
    """Mean height of the fill's top surface, from the highest grain top in each column away from the wall."""
    inner = np.hypot(pos[:, 0], pos[:, 1]) < radius - 2 * half_thickness.max()
    top = pos[:, 2] + half_thickness
    columns: dict[tuple[int, int], float] = {}
    for (x, y), z in zip(np.floor(pos[inner, :2] / cell).astype(int), top[inner]):
        columns[(x, y)] = max(columns.get((x, y), 0.0), z)
    return float(np.mean(list(columns.values())))


def heap_angles(pos: np.ndarray, half_thickness: np.ndarray, ring_width: float) -> tuple[float, float, float, float]:
    """A heap about the z axis: (height m, base radius m, height/base angle deg, slope-fit angle deg).

    A heap with too few rings on its flank for a fit has a NaN slope-fit angle.
    """
    top = pos[:, 2] + half_thickness
    r = np.hypot(pos[:, 0], pos[:, 1])
    profile = []
    for lo in np.arange(0.0, r.max() + ring_width, ring_width):
        ring = (r >= lo) & (r < lo + ring_width)
        if ring.any():
            profile.append((lo + ring_width / 2, top[ring].max()))
    profile = np.array(profile)
    height = float(profile[:, 1].max())
    layer = 2 * float(np.median(half_thickness))
    # the base ends where the surface drops to a single layer of grains
    beyond = np.flatnonzero(profile[:, 1] < 1.5 * layer)
    base = float(profile[beyond[0], 0] if beyond.size else profile[-1, 0])
    # heights above the single layer that covers the floor: a heap one grain high has no slope
    rise = max(0.0, height - layer)
    angle_hb = math.degrees(math.atan2(rise, base))
    above = profile[:, 1] - layer
    flank = (above > 0.2 * rise) & (above < 0.85 * rise) & (profile[:, 0] <= base)
    angle_fit = float("nan")
    if flank.sum() >= 3:
        slope = np.polyfit(profile[flank, 0], profile[flank, 1], 1)[0]
        angle_fit = math.degrees(math.atan(max(0.0, -slope)))
    return height, base, angle_hb, angle_fit
