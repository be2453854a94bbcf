"""A food's pile variants: the settled piles ScoopGranular draws from, and which one a loaded model holds."""

from __future__ import annotations

import functools
import re

import numpy as np

from veragmil_suite.environments.settling import SettledPile, pile_key, settle
from veragmil_suite.models.foods import FOODS, PHYSICS, FoodSpec
from veragmil_suite.models.grains import GrainPile

# pile variants tried when a loaded model's pile is identified (beyond the environment's own pile_variants)
LOADED_PILE_VARIANTS_TRIED = 64
# piles a process keeps built (a 200-grain rice pile holds about 0.3 MB): 4 variants of 7 foods in 2 physics fit
PILES_KEPT = 64


def pile_variant(food: FoodSpec, n_grains: int, physics: str, variant: int) -> GrainPile:
    """Pile variant ``variant`` of ``n_grains`` grains of ``food`` in ``physics`` (the same on every machine).

    Kept per process: a pile is a pure function of these four, and building one (drawing its grains, compiling the
    grains-only model its masses come from) took a third of a rice scene's hard reset. A food spec that cannot be a
    key (one holding a list) gets a new pile each time.
    """
    try:
        return kept_pile(food, n_grains, physics, variant)
    except TypeError:
        return _new_pile(food, n_grains, physics, variant)


@functools.lru_cache(maxsize=PILES_KEPT)
def kept_pile(food: FoodSpec, n_grains: int, physics: str, variant: int) -> GrainPile:
    """pile_variant's process-wide store (``kept_pile.cache_clear()`` empties it)."""
    return _new_pile(food, n_grains, physics, variant)


def _new_pile(food: FoodSpec, n_grains: int, physics: str, variant: int) -> GrainPile:
    rng = np.random.default_rng([variant, n_grains, *map(ord, food.name)])
    return GrainPile(food, n_grains, rng, physics=physics)


class PileVariantsMixin:
    """ScoopGranular's piles: each food and grain count has ``pile_variants`` piles, settled once per machine."""

    def _pile(
        self, variant: int, food: FoodSpec | None = None, n_grains: int | None = None, physics: str | None = None
    ) -> GrainPile:
        """Pile variant ``variant`` of this (or the given) food, grain count and physics."""
        food = self.food if food is None else food
        n_grains = self.n_grains if n_grains is None else n_grains
        physics = self.physics if physics is None else physics
        return pile_variant(food, int(n_grains), physics, int(variant))

    def settled_piles(self) -> dict[str, SettledPile]:
        """
        Every pile variant this environment can draw, settled here (or read from this machine's cache), by cache
        key: what a worker elsewhere is handed (veragmil_suite.environments.settling.use_shipped_piles) to reset this
        environment on the same piles, for any seed.
        """
        timestep = float(self.sim.model.opt.timestep)
        piles = {}
        for pile in self._variant_piles():
            settled = settle(self.bowl, pile, self.solver_options, timestep)
            piles[settled.key] = settled
        return piles

    def pile_keys(self) -> set[str]:
        """The cache keys of every pile variant this environment can draw, found without settling: a journaled
        episode that names another pile ran on a lattice or settling this code no longer builds."""
        timestep = float(self.sim.model.opt.timestep)
        return {pile_key(self.bowl, pile, self.solver_options, timestep) for pile in self._variant_piles()}

    def _variant_piles(self) -> list[GrainPile]:
        return [
            self._pile(variant, self._env_food, self._env_n_grains, self._env_physics)
            for variant in range(self.pile_variants)
        ]

    def _adopt_loaded_pile(self) -> None:
        """
        Makes food, n_grains, pile_variant and grain_pile those of the pile the simulation was built from.

        reset_from_xml_string (robosuite's playback, robomimic's reset_to, a merged dataset of several foods) may
        load a recorded XML of another food, grain count or pile variant than the one drawn last: the metrics and
        observations must use that pile's grain sizes and volumes. The pile is found among the environment's own
        food's and the catalog's (veragmil_suite.models.foods.FOODS) piles of the grain colour and count loaded.
        """
        model = self.sim.model
        pattern = re.compile(rf"{re.escape(self.grain_pile.name)}(\d+)")
        n_loaded = sum(1 for name in model.body_names if pattern.fullmatch(name))
        body_ids = [model.body_name2id(f"{self.grain_pile.name}{i}") for i in range(n_loaded)]
        first_geoms = model.body_geomadr[body_ids]
        loaded = model.geom_size[first_geoms]
        rgba = model.geom_rgba[first_geoms[0]] if n_loaded else None

        # saved XML keeps 6 significant digits; variants' sizes are drawn from a continuous range
        def holds(pile: GrainPile) -> bool:
            sizes = np.array([np.pad(g[0]["size"], (0, 3 - len(g[0]["size"]))) for g in pile.geoms])
            return np.allclose(sizes, loaded, rtol=1e-5, atol=0)

        if n_loaded == self.grain_pile.n_grains and holds(self.grain_pile):
            return
        foods = []
        for food in (self._env_food, self.food, *FOODS.values()):
            if all(food.name != f.name for f in foods):
                foods.append(food)
        tried = max(self.pile_variants, LOADED_PILE_VARIANTS_TRIED)
        physics_order = [self._env_physics, *(p for p in PHYSICS if p != self._env_physics)]
        for food in foods:
            if n_loaded == 0 or not np.allclose(food.rgba, rgba, atol=1e-5):
                continue
            for physics in physics_order:
                for variant in range(tried):
                    pile = self._pile(variant, food, n_loaded, physics)
                    if holds(pile):
                        self.food, self.n_grains, self.pile_variant, self.grain_pile = food, n_loaded, variant, pile
                        self.physics, self.grain = physics, food.grain(physics)
                        return
        raise ValueError(
            f"the loaded model's {n_loaded} grains are none of the first {tried} piles of {n_loaded} grains of any "
            f"known food ({', '.join(f.name for f in foods)}): register its food "
            "(veragmil_suite.models.foods.register_food) "
            "or make the environment with it"
        )
