"""A bent feeding spoon as a robosuite gripper with no actuated DoF."""

from __future__ import annotations

import numpy as np
from robosuite.models.grippers import register_gripper
from robosuite.models.grippers.gripper_model import GripperModel
from robosuite.utils.mjcf_utils import array_to_string, find_elements, new_geom
from robosuite.utils.transform_utils import convert_quat, mat2quat

from veragmil_suite.models import contact_groups
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import SPOON_CONTACT_SOLREF, SPOON_SURFACE
from veragmil_suite.utils.asset_paths import asset_path

# A feeding spoon: bowl 4.6 cm x 3.0 cm at the rim, 1 cm deep.
SPOON_SHAPE = DishShape(
    rim_semi_axes=(0.023, 0.015),
    floor_semi_axes=(0.013, 0.007),
    depth=0.010,
    wall_half_thickness=0.002,
    floor_half_thickness=0.002,
    n_walls=16,
)
HANDLE_LENGTH_M = 0.12  # flange to the back of the spoon's rim
BEND_RAD = np.pi / 4  # the spoon's bowl is bent this far from the handle's axis


def spoon_contact(physics: str) -> dict[str, str]:
    """The MJCF attributes of the spoon's collision geoms that depend on the physics (foods.SPOON_CONTACT_SOLREF):
    the spoon's spring wins the mix with any grain's (MuJoCo weighs two geoms' solref by their solmix)."""
    solref = SPOON_CONTACT_SOLREF[physics]
    return {} if solref is None else {"solref": array_to_string(solref), "solmix": "1000"}


def spoon_frame_in_flange() -> tuple[np.ndarray, np.ndarray]:
    """Position and (w, x, y, z) quaternion of the spoon frame (x to the tip, z out of the bowl) in the flange."""
    # Columns: the spoon's x (tip), y, z (opening) axes in flange coordinates, bent by BEND_RAD about flange y.
    s, c = np.sin(BEND_RAD), np.cos(BEND_RAD)
    rot = np.column_stack([[s, 0.0, c], [0.0, -1.0, 0.0], [c, 0.0, -s]])
    pos = np.array([0.0, 0.0, HANDLE_LENGTH_M]) + SPOON_SHAPE.rim_semi_axes[0] * rot[:, 0]
    return pos, convert_quat(mat2quat(rot), to="wxyz")


@register_gripper
class SpoonGripper(GripperModel):
    """
    A spoon rigidly mounted on the flange: a handle, and a concave bowl built from convex boxes so grains rest in
    it. The eef (grip_site) is the centre of the spoon's rim, so operational-space control turns the spoon about
    its bowl.

    Args:
        idn (int or str): Number or some other unique identification string for this gripper instance
    """

    def __init__(self, idn=0):
        super().__init__(asset_path("grippers/spoon_gripper.xml"), idn=idn)
        pos, quat = spoon_frame_in_flange()
        spoon_body = find_elements(self.root, "body", {"name": self.naming_prefix + "spoon"}, return_first=True)
        eef_body = find_elements(self.root, "body", {"name": self.naming_prefix + "eef"}, return_first=True)
        spoon_body.set("pos", array_to_string(pos))
        spoon_body.set("quat", array_to_string(quat))
        eef_body.set("pos", array_to_string(pos))
        for g in SPOON_SHAPE.geoms():
            name = "spoon_" + g["name"]
            common = dict(type=g["type"], size=g["size"], pos=g["pos"], quat=g["quat"], rgba=(0.78, 0.78, 0.8, 1))
            spoon_body.append(
                new_geom(
                    name=self.naming_prefix + name,
                    group=0,
                    friction=(SPOON_SURFACE.friction, 0.005, 0.0001),
                    density=SPOON_SURFACE.density_kg_m3,
                    condim=3,
                    **contact_groups.SHELL,
                    **common,
                )
            )
            spoon_body.append(
                new_geom(
                    name=self.naming_prefix + name + "_vis", group=1, contype=0, conaffinity=0, density=0, **common
                )
            )
            self._contact_geoms.append(name)
            self._visual_geoms.append(name + "_vis")
        handle = find_elements(self.root, "geom", {"name": self.naming_prefix + "handle_collision"}, return_first=True)
        for key, value in contact_groups.SHELL.items():
            handle.set(key, str(value))
        handle.set("friction", array_to_string((SPOON_SURFACE.friction, 0.005, 0.0001)))
        handle.set("density", str(SPOON_SURFACE.density_kg_m3))

    def format_action(self, action: np.ndarray) -> np.ndarray:
        return action

    @property
    def init_qpos(self) -> None:
        return None

    @property
    def _important_geoms(self):
        return {
            "left_finger": [],
            "right_finger": [],
            "left_fingerpad": [],
            "right_fingerpad": [],
            "spoon": ["handle_collision"] + [f"spoon_{g['name']}" for g in SPOON_SHAPE.geoms()],
        }

    @property
    def _important_sites(self):
        sites = super()._important_sites
        sites["spoon_frame"] = "spoon_frame"
        return sites
