"""A concave dish built from convex pieces: one floor box and a ring of sloped wall boxes.

MuJoCo collides convex geoms only, so both the spoon's bowl and the food bowl are shells of boxes. The walls
reach a little below the floor's top so no seam opens between floor and wall for a grain to wedge into.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from robosuite.utils.transform_utils import convert_quat, mat2quat


@dataclass(frozen=True)
class DishShape:
    """Dimensions of a dish, in metres, in the dish frame (origin at the rim's centre, z along the opening).

    Attributes:
        rim_semi_axes: (x, y) semi-axes of the rim ellipse.
        floor_semi_axes: (x, y) semi-axes of the floor ellipse (smaller than the rim: sloped walls).
        depth: from rim plane down to the floor's top surface.
        wall_half_thickness: half thickness of walls; thick walls keep fast grains from tunnelling.
        floor_half_thickness: half thickness of the floor; dropped grains sink several mm into a contact.
        n_walls: wall pieces around the ring.
        wall_overlap: tangential overlap factor of neighbouring wall pieces (closes the ring's gaps).
    """

    rim_semi_axes: tuple[float, float]
    floor_semi_axes: tuple[float, float]
    depth: float
    wall_half_thickness: float
    floor_half_thickness: float
    n_walls: int = 16
    wall_overlap: float = 1.15

    def holds(self, local: np.ndarray, margin: float = 0.0, above: float = 0.0) -> np.ndarray:
        """Which points (N x 3, in the dish frame) lie in the dish: inside the rim ellipse grown by ``margin``, no
        lower than ``margin`` under the floor's top and no higher than ``above`` over the rim plane."""
        a, b = self.rim_semi_axes
        return (
            ((local[:, 0] / (a + margin)) ** 2 + (local[:, 1] / (b + margin)) ** 2 <= 1.0)
            & (local[:, 2] >= -self.depth - margin)
            & (local[:, 2] <= above)
        )

    def geoms(self) -> list[dict]:
        """Geoms of the shell: dicts with name, type, pos, quat (w, x, y, z), size."""
        a, b = self.rim_semi_axes
        af, bf = self.floor_semi_axes
        t = self.wall_half_thickness
        out = [
            dict(
                name="floor",
                type="box",
                pos=np.array([0.0, 0.0, -self.depth - self.floor_half_thickness]),
                quat=np.array([1.0, 0.0, 0.0, 0.0]),
                size=np.array([af, bf, self.floor_half_thickness]),
            )
        ]
        seam = self.floor_half_thickness  # walls continue this far below the floor's top
        half_step = np.pi / self.n_walls
        for k, theta in enumerate(np.linspace(0.0, 2 * np.pi, self.n_walls, endpoint=False)):
            bottom = np.array([af * np.cos(theta), bf * np.sin(theta), -self.depth])
            top = np.array([a * np.cos(theta), b * np.sin(theta), 0.0])
            slope = top - bottom
            length = np.linalg.norm(slope)
            slope /= length
            bottom = bottom - slope * seam
            length += seam
            tangent = np.array([-a * np.sin(theta), b * np.cos(theta), 0.0])
            tangent -= tangent.dot(slope) * slope
            tangent /= np.linalg.norm(tangent)
            normal = np.cross(slope, tangent)
            mid = 0.5 * (bottom + top)
            if normal[:2].dot(mid[:2]) < 0:  # make the normal point away from the dish's axis
                normal, tangent = -normal, -tangent
            chord = np.hypot(
                a * (np.cos(theta + half_step) - np.cos(theta - half_step)),
                b * (np.sin(theta + half_step) - np.sin(theta - half_step)),
            )
            rot = np.column_stack([slope, tangent, normal])
            out.append(
                dict(
                    name=f"wall{k}",
                    type="box",
                    pos=mid + normal * t,  # the inner face passes through the floor edge and the rim
                    quat=convert_quat(mat2quat(rot), to="wxyz"),
                    size=np.array([length / 2, chord / 2 * self.wall_overlap, t]),
                )
            )
        return out

    @property
    def outer_radius(self) -> float:
        """Largest horizontal extent of the shell from its axis, including wall thickness."""
        return max(self.rim_semi_axes) + 2 * self.wall_half_thickness

    @property
    def height(self) -> float:
        """From the floor's bottom to the rim plane."""
        return self.depth + 2 * self.floor_half_thickness
