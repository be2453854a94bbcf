"""The scooping workspace: robosuite's table, with surfaces and cameras for granular food."""

from __future__ import annotations

import numpy as np
import robosuite.utils.transform_utils as T
from robosuite.models.arenas import TableArena
from robosuite.utils.mjcf_utils import array_to_string, new_element

from veragmil_suite.models import contact_groups
from veragmil_suite.models.foods import TABLE_SURFACE

# The overhead camera looks down at the bowl from above its far side (away from the robot), 55 degrees below the
# horizon: straight down from above the bowl, the arm's wrist filled half the frame at the pre-scoop pose.
OVERHEAD_CAMERA_OFFSET_M = (0.22, 0.0, 0.42)  # from the bowl's nominal place on the table top
OVERHEAD_CAMERA_FOVY_DEG = 40


class ScoopArena(TableArena):
    """
    A table whose top and the floor catch spilled grains, with a fixed ``overhead`` camera looking straight down
    at the bowl (the paper's RGB-D sensor) and robosuite's usual cameras.

    Args:
        table_full_size (3-tuple): (L,W,H) full dimensions of the table
        table_offset (3-tuple): (x,y,z) offset from center of arena when placing table
        bowl_xy (2-tuple): nominal bowl position on the table, in the table frame; the overhead camera centres it
    """

    def __init__(self, table_full_size=(0.8, 0.8, 0.05), table_offset=(0, 0, 0.8), bowl_xy=(0.0, 0.0)):
        friction = (TABLE_SURFACE.friction, 0.005, 0.0001)
        super().__init__(table_full_size=table_full_size, table_friction=friction, table_offset=table_offset)
        for geom in (self.table_collision, self.floor):
            for key, value in contact_groups.SUPPORT.items():
                geom.set(key, str(value))
        target = np.array(table_offset) + np.array([bowl_xy[0], bowl_xy[1], 0.0])
        camera_pos = target + np.array(OVERHEAD_CAMERA_OFFSET_M)
        self.worldbody.append(
            new_element(
                "camera",
                name="overhead",
                mode="fixed",
                pos=array_to_string(camera_pos),
                quat=array_to_string(look_at_quat(camera_pos, target)),
                fovy=str(OVERHEAD_CAMERA_FOVY_DEG),
            )
        )


def look_at_quat(camera_pos: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(w, x, y, z) orientation of a MuJoCo camera (looking along its -z, image up +y) at ``camera_pos`` facing
    ``target`` with the world's z axis up in the image."""
    back = camera_pos - target
    back = back / np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return T.convert_quat(T.mat2quat(np.column_stack([right, up, back])), to="wxyz")
