"""The scooping workspace: robosuite's table, with surfaces and cameras for granular food."""

from __future__ import annotations

import numpy as np
from robosuite.models.arenas import TableArena
from robosuite.utils.mjcf_utils import array_to_string, new_element

from veragmil_suite.foods import TABLE_SURFACE
from veragmil_suite.models import contact_groups

OVERHEAD_CAMERA_HEIGHT_M = 0.45  # above the table top: the bowl and the carry path fill the frame
OVERHEAD_CAMERA_FOVY_DEG = 45


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
        camera_pos = np.array(table_offset) + np.array([bowl_xy[0], bowl_xy[1], OVERHEAD_CAMERA_HEIGHT_M])
        # Looking straight down; image up is +x (away from the robot), so the robot enters from the bottom.
        self.worldbody.append(
            new_element(
                "camera",
                name="overhead",
                mode="fixed",
                pos=array_to_string(camera_pos),
                quat=array_to_string((0.7071068, 0.0, 0.0, -0.7071068)),
                fovy=str(OVERHEAD_CAMERA_FOVY_DEG),
            )
        )
