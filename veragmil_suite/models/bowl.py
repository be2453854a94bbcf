"""The food bowl: a heavy dish on a high-friction foot, free to be nudged but not to slide."""

from __future__ import annotations

import numpy as np
from robosuite.models.objects import CompositeObject

from veragmil_suite.models import contact_groups
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import BOWL_FOOT_SURFACE, BOWL_SURFACE

# Default bowl: 11 cm across at the rim, 4 cm deep, walls sloped at 45 degrees down to a 3 cm floor, so a few
# hundred grains gather into a heap a spoon can dig into (a flat 6 cm floor spread 200 rice grains one layer
# thin). Thick walls and floor: dropped grains sink millimetres into a contact and tunnel through thin ones.
DEFAULT_BOWL_SHAPE = DishShape(
    rim_semi_axes=(0.055, 0.055),
    floor_semi_axes=(0.015, 0.015),
    depth=0.04,
    wall_half_thickness=0.01,
    floor_half_thickness=0.01,
    n_walls=20,
)
FOOT_HALF_HEIGHT_M = 0.002  # the foot ring stands this far below the floor, so only the foot touches the table
SKIRT_HALF_THICKNESS_M = 0.003
SKIRT_CLEARANCE_M = 0.001


class Bowl(CompositeObject):
    """
    The food bowl as a free body. Its origin is the centre of its bounding box; ``rim_offset`` is the rim's
    centre relative to it.

    Args:
        name (str): Name of this object
        shape (DishShape): dimensions of the bowl
        rgba (4-tuple): colour, chosen to contrast with pale grains in the overhead camera
    """

    def __init__(self, name: str, shape: DishShape = DEFAULT_BOWL_SHAPE, rgba=(0.25, 0.4, 0.65, 1.0)):
        self.shape = shape
        height = shape.height + 2 * FOOT_HALF_HEIGHT_M
        self.rim_offset = np.array([0.0, 0.0, height / 2])
        geoms = shape.geoms()
        foot_radius = 0.7 * min(shape.floor_semi_axes)
        geoms.append(
            dict(
                name="foot",
                type="box",
                pos=np.array([0.0, 0.0, -shape.height - FOOT_HALF_HEIGHT_M]),
                quat=np.array([1.0, 0.0, 0.0, 0.0]),
                size=np.array([foot_radius, foot_radius, FOOT_HALF_HEIGHT_M]),
            )
        )
        # the skirt stops a millimetre above the table: narrower than any grain, and it never rubs on the table
        geoms += _skirt(shape, bottom_z=-shape.height - 2 * FOOT_HALF_HEIGHT_M + SKIRT_CLEARANCE_M)
        r = shape.outer_radius + 2 * SKIRT_HALF_THICKNESS_M
        super().__init__(
            name=name,
            total_size=[r, r, height / 2],
            geom_types=[g["type"] for g in geoms],
            geom_sizes=[g["size"] for g in geoms],
            geom_locations=[g["pos"] + self.rim_offset for g in geoms],
            geom_quats=[g["quat"] for g in geoms],
            geom_names=[g["name"] for g in geoms],
            geom_frictions=[
                (BOWL_FOOT_SURFACE.friction if g["name"] == "foot" else BOWL_SURFACE.friction, 0.005, 0.0001)
                for g in geoms
            ],
            geom_condims=[3] * len(geoms),
            rgba=rgba,
            density=BOWL_SURFACE.density_kg_m3,
            locations_relative_to_center=True,
            joints="default",
        )
        for geom in self.get_obj().iter("geom"):
            if geom.get("group") == "1":
                continue
            bits = contact_groups.BOWL_FOOT if geom.get("name").endswith("foot") else contact_groups.SHELL
            for key, value in bits.items():
                geom.set(key, str(value))


def _skirt(shape: DishShape, bottom_z: float) -> list[dict]:
    """Vertical outer walls from the table to the rim, closing the overhang under the sloped walls.

    A grain that rolled under the overhang was pressed into the table by the bowl's whole weight (MuJoCo's soft
    contacts scale with the grain's tiny mass) and sank a centimetre into it.
    """
    radius = shape.outer_radius + SKIRT_HALF_THICKNESS_M
    half_height = -bottom_z / 2
    chord = 2 * radius * np.sin(np.pi / shape.n_walls)
    out = []
    for k, theta in enumerate(np.linspace(0.0, 2 * np.pi, shape.n_walls, endpoint=False)):
        out.append(
            dict(
                name=f"skirt{k}",
                type="box",
                pos=np.array([radius * np.cos(theta), radius * np.sin(theta), bottom_z / 2]),
                quat=np.array([np.cos(theta / 2), 0.0, 0.0, np.sin(theta / 2)]),
                size=np.array([SKIRT_HALF_THICKNESS_M, chord / 2 * shape.wall_overlap, half_height]),
            )
        )
    return out
