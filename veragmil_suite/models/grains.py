"""A pile of grains: free bodies generated procedurally from a food's catalog entry."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from robosuite.utils.mjcf_utils import array_to_string, new_body, new_geom

from veragmil_suite.foods import GRAIN_SOLIMP, FoodSpec
from veragmil_suite.models import contact_groups
from veragmil_suite.models.dish import DishShape

# Lower bound of a grain's principal inertia, as a fraction of mass * (size/2)^2 (a solid sphere is 0.4).
GRAIN_MIN_INERTIA_FACTOR = 0.4


class GrainPile:
    """
    N grains of one food, each a free body, first placed on a jittered lattice inside the bowl without overlap
    (they settle into a pile afterwards: see veragmil_suite.settling).

    Args:
        food (FoodSpec): the food
        n_grains (int): how many grains
        rng (np.random.Generator): draws every grain's size and starting pose; the same seed gives the same XML
        name (str): prefix of the bodies, joints and geoms
    """

    def __init__(self, food: FoodSpec, n_grains: int, rng: np.random.Generator, name: str = "grain"):
        if n_grains <= 0:
            raise ValueError(f"n_grains must be a positive integer, got {n_grains!r}")
        self.food = food
        self.n_grains = int(n_grains)
        self.name = name
        self.sizes = food.sample_sizes(rng, self.n_grains)
        self.geoms = [food.grain_geoms(s) for s in self.sizes]
        # Bounding radius of each grain in its body frame: placement spacing uses it.
        self.radii = np.array([_bounding_radius(g) for g in self.geoms])
        self.volumes_m3 = np.array([food.piece_volume_m3(s) for s in self.sizes])
        self._orientation_seed = int(rng.integers(2**31))
        self._mass_properties = None

    @property
    def body_names(self) -> list[str]:
        return [f"{self.name}{i}" for i in range(self.n_grains)]

    @property
    def joint_names(self) -> list[str]:
        return [f"{self.name}{i}_joint" for i in range(self.n_grains)]

    def mass_properties(self) -> dict[str, np.ndarray]:
        """Each grain's mass, centre of mass, inertia frame and diagonal inertia, with the inertia floor applied.

        MuJoCo integrates them from the geometry and density in a grains-only model (robosuite's compiler counts
        only geom group 0 towards inertia, and grains are drawn in group 1, so every grain carries an explicit
        ``<inertial>``). A millimetre grain's rotational inertia is so small (rice: 4e-12 kg m^2) that one contact
        torque sends its angular acceleration past 1e10 and MuJoCo resets the whole simulation; each principal
        inertia is therefore raised to at least GRAIN_MIN_INERTIA_FACTOR * mass * (size/2)^2.
        """
        if self._mass_properties is None:
            root = ET.Element("mujoco")
            world = ET.SubElement(root, "worldbody")
            for body in self._bodies(inertials=None):
                world.append(body)
            model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
            ids = np.array([model.body(name).id for name in self.body_names])
            mass = model.body_mass[ids].copy()
            floor = GRAIN_MIN_INERTIA_FACTOR * mass * (self.sizes / 2) ** 2
            self._mass_properties = dict(
                mass=mass,
                ipos=model.body_ipos[ids].copy(),
                iquat=model.body_iquat[ids].copy(),
                inertia=np.maximum(model.body_inertia[ids], floor[:, None]),
            )
        return self._mass_properties

    def bodies(self) -> list[ET.Element]:
        """The grains' bodies (at the origin: their poses live in qpos), ready to append to a worldbody."""
        return self._bodies(inertials=self.mass_properties())

    def _bodies(self, inertials: dict | None) -> list[ET.Element]:
        solref = array_to_string(self.food.solref)
        solimp = array_to_string(GRAIN_SOLIMP)
        friction = array_to_string((self.food.friction, 0.005, 0.0001))
        out = []
        for i, geoms in enumerate(self.geoms):
            body = new_body(name=f"{self.name}{i}", pos=(0, 0, 0))
            body.append(ET.Element("freejoint", name=f"{self.name}{i}_joint"))
            if inertials is not None:
                body.append(
                    ET.Element(
                        "inertial",
                        pos=array_to_string(inertials["ipos"][i]),
                        quat=array_to_string(inertials["iquat"][i]),
                        mass=repr(float(inertials["mass"][i])),
                        diaginertia=array_to_string(inertials["inertia"][i]),
                    )
                )
            for k, g in enumerate(geoms):
                geom = new_geom(
                    name=f"{self.name}{i}_g{k}",
                    type=g["type"],
                    size=g["size"],
                    pos=g["pos"],
                    quat=g["quat"],
                    rgba=self.food.rgba,
                    density=self.food.density_kg_m3,
                    condim=3,
                    group=1,
                    **contact_groups.GRAIN,
                )
                geom.set("friction", friction)
                geom.set("solref", solref)
                geom.set("solimp", solimp)
                body.append(geom)
            out.append(body)
        return out

    def lattice_qpos(self, bowl: DishShape, rim_center: np.ndarray) -> np.ndarray:
        """Starting poses (n, 7: pos, wxyz quat) on a jittered lattice inside the bowl, free of overlaps.

        Layers stack upward from the floor; each layer fills the bowl's cross-section at its height (narrower
        than the rim, so every grain falls inside the bowl).
        """
        rng = np.random.default_rng(self._orientation_seed)
        spacing = 2 * self.radii.max() * 1.05
        floor_z = rim_center[2] - bowl.depth
        r_floor, r_rim = min(bowl.floor_semi_axes), min(bowl.rim_semi_axes)
        positions = []
        z = floor_z + spacing / 2
        layer = 0
        while len(positions) < self.n_grains:
            height = min(z - floor_z, bowl.depth)
            radius = r_floor + (r_rim - r_floor) * height / bowl.depth - spacing / 2 - bowl.wall_half_thickness
            offset = 0.5 * spacing * (layer % 2)
            ticks = np.arange(-radius, radius + 1e-9, spacing)
            for x in ticks:
                for y in ticks:
                    if np.hypot(x + offset, y + offset) <= radius:
                        positions.append((rim_center[0] + x + offset, rim_center[1] + y + offset, z))
            z += spacing
            layer += 1
        order = rng.permutation(len(positions))[: self.n_grains]
        pos = np.array(positions)[order]
        pos[:, :2] += rng.uniform(-0.02, 0.02, size=(self.n_grains, 2)) * spacing
        quat = rng.normal(size=(self.n_grains, 4))
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        return np.hstack([pos, quat])


def _bounding_radius(geoms: list[dict]) -> float:
    radius = 0.0
    for g in geoms:
        size = np.asarray(g["size"], dtype=float)
        if g["type"] == "capsule":
            extent = size[0] + size[1]
        elif g["type"] == "box":
            extent = float(np.linalg.norm(size))
        else:
            extent = float(size.max())
        radius = max(radius, float(np.linalg.norm(g["pos"])) + extent)
    return radius
