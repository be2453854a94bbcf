"""The food catalog: every physical constant of a granular food lives here, and only here.

The seven foods are Table I of the VERAGMIL paper (shape, size range, friction, restitution, density). Each is
mapped to MuJoCo geometry that keeps contacts cheap and stable:

==========  ============  ===================================================================
food        Table I shape MuJoCo geometry (per grain)
==========  ============  ===================================================================
rice        elongated     two overlapping spheres (radius ``aspect[0]`` * size / 2) spanning ``size``: sphere
                          contacts are analytic, 10x cheaper than ellipsoids; capsules never came to rest
buckwheat   triangular    compound of three spheres in a triangle (a rounded triangular seed)
barley      oval          two overlapping spheres, like rice but plumper
pasta       cylindrical   capsule (a short tube seen from the outside)
peas        spherical     sphere of diameter = size
beans       oval          ellipsoid
flakes      irregular     compound of two flattened ellipsoids at a slant (a curled flake)
==========  ============  ===================================================================

``size`` is the longest dimension in metres, drawn uniformly from Table I's range for every grain. Mass comes
from the geometry's volume times density (MuJoCo integrates it from ``density``). Sliding friction is Table I's
coefficient. Restitution ``e`` becomes contact damping: a MuJoCo contact is a damped spring, and a damped
oscillator that rebounds with coefficient ``e`` has damping ratio ``zeta = -ln e / sqrt(pi^2 + ln^2 e)``; with
``solref = (CONTACT_TIMECONST_S, zeta)`` (a 0.02 s time constant) this reproduced e = 0.10/0.15/0.20 as
0.10/0.17/0.21 at a 2 ms step; tests/test_foods.py measures it at our time constant and step.

A user adds a food without editing this file: ``register_food(FoodSpec(...))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Contact spring time constant (s) shared by all grains: above 2x the 1/240 s physics step (MuJoCo's stability
# rule). A stiffer 0.01 s threw buckwheat out of the bowl while settling.
CONTACT_TIMECONST_S = 0.02

# Contact impedance (MuJoCo solimp: dmin, dmax, width in m). A narrow transition keeps grains from sinking.
GRAIN_SOLIMP = (0.95, 0.99, 0.001)

SHAPES = ("capsule", "sphere", "ellipsoid", "box", "sphere_pair", "spheres_triangle", "flake_pair")


@dataclass(frozen=True)
class FoodSpec:
    """One granular food.

    Attributes:
        name: catalog key.
        shape: one of SHAPES (the MuJoCo geometry, see the module docstring).
        size_range_m: (min, max) longest dimension of a grain, metres.
        friction: sliding friction coefficient (Table I).
        restitution: coefficient of restitution (Table I), mapped to contact damping.
        density_kg_m3: density, kg/m^3 (Table I gives g/cm^3; x1000).
        aspect: the other dimensions as fractions of ``size`` (meaning depends on the shape, see module doc).
        default_grains: grain count of the default scene (chosen for a scoopable pile at real time).
        rgba: display colour.
    """

    name: str
    shape: str
    size_range_m: tuple[float, float]
    friction: float
    restitution: float
    density_kg_m3: float
    aspect: tuple[float, ...]
    default_grains: int
    rgba: tuple[float, float, float, float] = (0.9, 0.9, 0.85, 1.0)
    table_shape: str = field(default="", compare=False)

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise ValueError(f"Food {self.name!r}: unknown shape {self.shape!r}; accepted shapes: {', '.join(SHAPES)}")
        lo, hi = self.size_range_m
        if not 0 < lo <= hi:
            raise ValueError(f"Food {self.name!r}: size_range_m must satisfy 0 < min <= max, got {self.size_range_m}")
        if not 0 < self.restitution < 1:
            raise ValueError(f"Food {self.name!r}: restitution must lie in (0, 1), got {self.restitution}")
        if self.friction <= 0 or self.density_kg_m3 <= 0 or self.default_grains <= 0:
            raise ValueError(f"Food {self.name!r}: friction, density and default_grains must be positive")

    @property
    def damping_ratio(self) -> float:
        """Contact damping ratio that rebounds with this food's restitution (see module docstring)."""
        log_e = math.log(self.restitution)
        return -log_e / math.sqrt(math.pi**2 + log_e**2)

    @property
    def solref(self) -> tuple[float, float]:
        """MuJoCo solref (timeconst s, damping ratio) of this food's contacts."""
        return (CONTACT_TIMECONST_S, self.damping_ratio)

    @property
    def mean_size_m(self) -> float:
        return 0.5 * (self.size_range_m[0] + self.size_range_m[1])

    def piece_volume_m3(self, size_m: float | None = None) -> float:
        """Volume of one grain of longest dimension ``size_m`` (the mean size by default), m^3."""
        s = self.mean_size_m if size_m is None else size_m
        if self.shape == "capsule":
            r = self.aspect[0] * s / 2
            return math.pi * r**2 * (s - 2 * r) + 4 / 3 * math.pi * r**3
        if self.shape == "sphere":
            return 4 / 3 * math.pi * (s / 2) ** 3
        if self.shape == "ellipsoid":
            a = s / 2
            return 4 / 3 * math.pi * a * (a * self.aspect[0]) * (a * self.aspect[1])
        if self.shape == "box":
            return s * (s * self.aspect[0]) * (s * self.aspect[1])
        if self.shape == "sphere_pair":
            r = self.aspect[0] * s / 2
            d = s - 2 * r  # centre distance; the spheres overlap where d < 2r (a lens counted twice, removed)
            lens = math.pi * (4 * r + d) * (2 * r - d) ** 2 / 12 if d < 2 * r else 0.0
            return 2 * 4 / 3 * math.pi * r**3 - lens
        if self.shape == "spheres_triangle":
            r = _triangle_sphere_radius(s)
            return 3 * 4 / 3 * math.pi * r**3
        # flake_pair: two half flakes
        a = s / 4
        return 2 * 4 / 3 * math.pi * a * (s / 2 * self.aspect[0]) * (s / 2 * self.aspect[1])

    def sample_sizes(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Longest dimension of ``n`` grains, m, uniform over Table I's range."""
        return rng.uniform(*self.size_range_m, size=n)

    def grain_geoms(self, size_m: float) -> list[dict]:
        """Geoms (MuJoCo attributes, body frame) of one grain whose longest dimension is ``size_m``."""
        s = float(size_m)
        if self.shape == "capsule":
            r = self.aspect[0] * s / 2
            return [dict(type="capsule", size=(r, s / 2 - r), pos=(0, 0, 0), quat=(1, 0, 0, 0))]
        if self.shape == "sphere":
            return [dict(type="sphere", size=(s / 2,), pos=(0, 0, 0), quat=(1, 0, 0, 0))]
        if self.shape == "ellipsoid":
            a = s / 2
            return [dict(type="ellipsoid", size=(a, a * self.aspect[0], a * self.aspect[1]), pos=(0, 0, 0),
                         quat=(1, 0, 0, 0))]  # fmt: skip
        if self.shape == "box":
            h = s / 2
            return [dict(type="box", size=(h, h * self.aspect[0], h * self.aspect[1]), pos=(0, 0, 0),
                         quat=(1, 0, 0, 0))]  # fmt: skip
        if self.shape == "sphere_pair":
            r = self.aspect[0] * s / 2
            return [
                dict(type="sphere", size=(r,), pos=(sign * (s / 2 - r), 0, 0), quat=(1, 0, 0, 0)) for sign in (1, -1)
            ]
        if self.shape == "spheres_triangle":
            r = _triangle_sphere_radius(s)
            c = (s - 2 * r) / math.sqrt(3)  # circumradius of the triangle of sphere centres
            return [
                dict(type="sphere", size=(r,), pos=(c * math.cos(t), c * math.sin(t), 0), quat=(1, 0, 0, 0))
                for t in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)
            ]
        # flake_pair: two flattened ellipsoids meeting at a slant, so flakes do not stack like coins
        half = s / 4
        slant = math.radians(self.aspect[2])
        q = (math.cos(slant / 2), 0.0, math.sin(slant / 2), 0.0)
        q_neg = (q[0], 0.0, -q[2], 0.0)
        axes = (half, s / 2 * self.aspect[0], s / 2 * self.aspect[1])
        return [
            dict(type="ellipsoid", size=axes, pos=(half * 0.9, 0, 0), quat=q),
            dict(type="ellipsoid", size=axes, pos=(-half * 0.9, 0, 0), quat=q_neg),
        ]


def _triangle_sphere_radius(size_m: float) -> float:
    """Radius of each of the three spheres of a triangular grain whose longest extent is ``size_m``."""
    # Three equal spheres in an equilateral triangle with centre spacing 1.2 r span 2r + 1.2r.
    return size_m / 3.2


# Table I of the paper. Sizes are metres (Table I: cm), densities kg/m^3 (Table I: g/cm^3).
# ``aspect`` and ``default_grains`` are our choices: aspect from typical grain proportions (rice is short-grain,
# width 0.55 of length: a heap twice the volume of long-grain for the same contacts), grain counts from the
# default-scene study (README, "Physics").
FOODS: dict[str, FoodSpec] = {}


def register_food(food: FoodSpec, overwrite: bool = False) -> FoodSpec:
    """Adds a food to the catalog so that ``robosuite.make("ScoopGranular", food=name)`` accepts it."""
    if food.name in FOODS and not overwrite:
        raise ValueError(f"Food {food.name!r} is already in the catalog; pass overwrite=True to replace it")
    FOODS[food.name] = food
    return food


for _food in (
    # name, shape, size range (m), friction, restitution, density (kg/m^3), aspect, default grains, rgba, Table I shape
    FoodSpec("rice", "sphere_pair", (0.005, 0.007), 0.20, 0.10, 1450.0, (0.55,), 200, (0.96, 0.95, 0.9, 1), "Elongated"),
    FoodSpec("beans", "ellipsoid", (0.010, 0.018), 0.25, 0.20, 1000.0, (0.65, 0.5), 60, (0.55, 0.2, 0.15, 1), "Oval"),
    FoodSpec("buckwheat", "spheres_triangle", (0.004, 0.006), 0.30, 0.10, 780.0, (), 150, (0.6, 0.42, 0.25, 1), "Triangular"),
    FoodSpec("peas", "sphere", (0.006, 0.008), 0.22, 0.20, 720.0, (), 150, (0.45, 0.75, 0.25, 1), "Spherical"),
    FoodSpec("barley", "sphere_pair", (0.008, 0.012), 0.18, 0.15, 1250.0, (0.55,), 120, (0.85, 0.78, 0.6, 1), "Oval"),
    FoodSpec("flakes", "flake_pair", (0.012, 0.020), 0.15, 0.05, 400.0, (0.8, 0.12, 20.0), 80, (0.9, 0.7, 0.3, 1), "Irregular"),
    FoodSpec("pasta", "capsule", (0.020, 0.035), 0.25, 0.10, 1200.0, (0.28,), 40, (0.98, 0.85, 0.45, 1), "Cylindrical"),
):  # fmt: skip
    register_food(_food)

# The paper's split (Section IV-A): trained on four foods, generalization measured on three unseen ones.
TRAINING_FOODS: tuple[str, ...] = ("rice", "buckwheat", "barley", "pasta")
UNSEEN_FOODS: tuple[str, ...] = ("peas", "beans", "flakes")


def get_food(food: str | FoodSpec) -> FoodSpec:
    """Looks a food up by name; a FoodSpec passes through unchanged."""
    if isinstance(food, FoodSpec):
        return food
    if food not in FOODS:
        raise ValueError(f"Unknown food {food!r}; accepted foods: {', '.join(sorted(FOODS))}")
    return FOODS[food]


@dataclass(frozen=True)
class Surface:
    """A non-food surface of the scene.

    MuJoCo takes the larger of two geoms' friction coefficients for a contact. Spoon and bowl are set below every
    food's coefficient so that each food-on-tool contact uses the food's own Table I value.

    Attributes:
        friction: sliding friction coefficient.
        density_kg_m3: density, kg/m^3.
    """

    friction: float
    density_kg_m3: float


SPOON_SURFACE = Surface(friction=0.1, density_kg_m3=7800.0)  # stainless steel
BOWL_SURFACE = Surface(friction=0.1, density_kg_m3=2400.0)  # glazed ceramic
BOWL_FOOT_SURFACE = Surface(friction=1.0, density_kg_m3=2400.0)  # unglazed foot ring on a table: the bowl stays
TABLE_SURFACE = Surface(friction=0.1, density_kg_m3=700.0)  # a spilled grain keeps its own friction on the table
