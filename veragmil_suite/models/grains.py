"""A pile of grains: free bodies generated procedurally from a food's catalog entry."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
from robosuite.utils.mjcf_utils import array_to_string, new_body, new_geom

from veragmil_suite.models import contact_groups
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import DEFAULT_PHYSICS, GRAIN_SOLIMP, FoodSpec

# Lower bound of a grain's principal inertia, as a fraction of mass * (size/2)^2 (a solid sphere is 0.4).
GRAIN_MIN_INERTIA_FACTOR = 0.4
# Free-joint damping per grain, as a spin decay rate (1/s) times its smallest principal inertia. It stops grains
# rolling within ~1/rate seconds; on translation the same damping decays speed at 1e-4/s (negligible).
GRAIN_SPIN_DECAY_PER_S = 20.0


class GrainPile:
    """
    N grains of one food, each a free body, first placed on a jittered lattice inside the bowl without overlap
    (they settle into a pile afterwards: see veragmil_suite.environments.settling). Its per-grain arrays (sizes, radii,
    volumes, mass properties) are read-only: one pile serves every environment of a process that draws it
    (veragmil_suite.environments.pile_variants).

    Args:
        food (FoodSpec): the food
        n_grains (int): how many grains
        rng (np.random.Generator): draws every grain's size and starting pose; the same seed gives the same XML
        name (str): prefix of the bodies, joints and geoms
        physics (str): which of the food's grain models ("calibrated" or "table1", veragmil_suite.models.foods.PHYSICS)
    """

    def __init__(
        self,
        food: FoodSpec,
        n_grains: int,
        rng: np.random.Generator,
        name: str = "grain",
        physics: str = DEFAULT_PHYSICS,
    ):
        if n_grains <= 0:
            raise ValueError(f"n_grains must be a positive integer, got {n_grains!r}")
        self.food = food
        self.physics = physics
        self.grain = food.grain(physics)
        self.n_grains = int(n_grains)
        self.name = name
        self.sizes = self.grain.sample_sizes(rng, self.n_grains)
        self.geoms = [self.grain.grain_geoms(s) for s in self.sizes]
        # Bounding radius of each grain in its body frame: placement spacing uses it.
        self.radii = np.array([_bounding_radius(g) for g in self.geoms])
        self.volumes_m3 = np.array([self.grain.piece_volume_m3(s) for s in self.sizes])
        self._orientation_seed = int(rng.integers(2**31))
        self._mass_properties = None
        _read_only(self.sizes, self.radii, self.volumes_m3)

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
            _read_only(*self._mass_properties.values())
        return self._mass_properties

    def bodies(self, home_qpos: np.ndarray | None = None) -> list[ET.Element]:
        """The grains' bodies, ready to append to a worldbody.

        Args:
            home_qpos: (n, 7) poses written into the XML (MuJoCo's qpos0). robosuite runs the physics forward
                several times before a task places its objects; grains all at the origin would overlap in one
                point and cost 1.5 s per forward, so the task passes a spread-out arrangement.
        """
        out = self._bodies(inertials=self.mass_properties())
        if home_qpos is not None:
            for body, q in zip(out, home_qpos):
                body.set("pos", array_to_string(q[:3]))
                body.set("quat", array_to_string(q[3:]))
        return out

    def _bodies(self, inertials: dict | None) -> list[ET.Element]:
        grain = self.grain
        solref = array_to_string(grain.solref)
        solimp = array_to_string(GRAIN_SOLIMP)
        friction = array_to_string(grain.friction_triplet)
        out = []
        for i, geoms in enumerate(self.geoms):
            body = new_body(name=f"{self.name}{i}", pos=(0, 0, 0))
            joint = ET.SubElement(body, "joint", name=f"{self.name}{i}_joint", type="free")
            if inertials is not None:
                # Rolling resistance: real grains are not perfect capsules and stop rolling; an ideal one on a
                # flat floor rolls forever (condim 3 has no rolling friction), so the pile never comes to rest.
                damping = GRAIN_SPIN_DECAY_PER_S * float(inertials["inertia"][i].min())
                joint.set("damping", repr(damping))
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
                    density=float(grain.density_kg_m3),
                    condim=grain.condim,
                    group=1,
                    **contact_groups.GRAIN,
                )
                geom.set("friction", friction)
                geom.set("solref", solref)
                geom.set("solimp", solimp)
                if grain.margin_m > 0:
                    geom.set("margin", repr(grain.margin_m))
                body.append(geom)
            out.append(body)
        return out

    def lattice_qpos(self, bowl: DishShape, rim_center: np.ndarray) -> np.ndarray:
        """Starting poses (n, 7: pos, wxyz quat) on a jittered lattice in and above the bowl, free of overlaps.

        Grains lie with their long axis horizontal and a random heading, so a layer is as thick as a grain
        (not as long): long pasta would otherwise start a metre up and hit the pile hard enough to tunnel. Layers
        span the bowl's cross-section at their height, at most the rim (the sloped walls funnel grains inward).
        A dish whose rim fits no lattice point (pasta or flakes on a spoon) takes one grain a layer at its centre.
        """
        rng = np.random.default_rng(self._orientation_seed)
        spacing = 2 * self.radii.max() * 1.05
        layer_height = 2 * self.thickness_radii.max() * 1.1
        floor_z = rim_center[2] - bowl.depth
        r_floor, r_rim = min(bowl.floor_semi_axes), min(bowl.rim_semi_axes)
        positions = []
        empty_at_rim = 0
        z = floor_z + layer_height / 2
        layer = 0
        while len(positions) < self.n_grains:
            height = min(z - floor_z, bowl.depth)
            radius = r_floor + (r_rim - r_floor) * height / bowl.depth - spacing / 2
            offset = 0.5 * spacing * (layer % 2)
            ticks = np.arange(-radius - offset, radius + spacing, spacing)
            placed = len(positions)
            for x in ticks:
                for y in ticks:
                    if np.hypot(x, y) <= radius:
                        positions.append((rim_center[0] + x, rim_center[1] + y, z))
            empty_at_rim = empty_at_rim + 1 if len(positions) == placed and height >= bowl.depth else 0
            if empty_at_rim >= 2:  # neither offset of the lattice fits inside the rim, nor will any layer above
                positions.append((rim_center[0], rim_center[1], z))
            z += layer_height
            layer += 1
        order = rng.permutation(len(positions))[: self.n_grains]
        pos = np.array(positions)[order]
        yaw = rng.uniform(-np.pi, np.pi, self.n_grains)
        # each grain's long axis: capsules are long along z, the other shapes along x
        lay_down = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])  # 90 degrees about x
        quat = np.stack([np.cos(yaw / 2), np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2)], axis=1)
        if self.geoms[0][0]["type"] == "capsule":
            quat = np.array([_quat_mul(q, lay_down) for q in quat])
        return np.hstack([pos, quat])

    @property
    def thickness_radii(self) -> np.ndarray:
        """Half of each grain's vertical extent when it lies on its long side (for layer spacing)."""
        out = []
        for geoms in self.geoms:
            g = geoms[0]
            size = np.asarray(g["size"], dtype=float)
            if g["type"] in ("capsule", "sphere"):
                out.append(size[0])
            elif g["type"] == "spheres_triangle":
                out.append(size[0])
            elif len(geoms) == 1:
                extent = max(float(size[1:].max()), float(np.abs(np.asarray(g["pos"])[2:]).max(initial=0.0)))
                out.append(extent)
            else:  # parts of a bent grain (a flake): each part's reach along the body's z, tilt included
                out.append(max(_vertical_reach(part) for part in geoms))
        return np.array(out)


def _quat_mul(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Hamilton product of two (w, x, y, z) quaternions."""
    w0, x0, y0, z0 = q
    w1, x1, y1, z1 = p
    return np.array(
        [
            w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
            w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
            w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
            w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
        ]
    )


def _vertical_reach(geom: dict) -> float:
    """How far above its body's origin an ellipsoid or box part reaches, given its offset and rotation."""
    size = np.asarray(geom["size"], dtype=float)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(geom["quat"], dtype=float))
    row = np.abs(rotation.reshape(3, 3)[2])  # the part's axes' components along the body's z
    half = float(np.linalg.norm(row * size)) if geom["type"] == "ellipsoid" else float(row @ size)
    return abs(float(np.asarray(geom["pos"], dtype=float)[2])) + half


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


def _read_only(*arrays: np.ndarray) -> None:
    for array in arrays:
        array.setflags(write=False)
