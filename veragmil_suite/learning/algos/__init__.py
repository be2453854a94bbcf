"""
Algorithms of ours for robomimic 0.3.0, registered the way robomimic registers its own: a config class (named by
its ``ALGO_NAME`` through robomimic's config metaclass) and an algo factory function (``register_algo_factory_func``).
robomimic's train loop, its checkpoints (``policy_from_checkpoint``) and its rollouts then use them unchanged.

- ``diffusion_policy``: Diffusion Policy (veragmil_suite.learning.algos.diffusion_policy).

Importing veragmil_suite calls :func:`register_on_import`, which registers them without importing robomimic or
torch itself (most of the package's programs never train): each module of ours is imported right after the robomimic
package whose registry it fills (``robomimic.config``, ``robomimic.algo``) has been imported, by whichever program
imports it, or at once when robomimic is imported already.
"""

from __future__ import annotations

import importlib
import importlib.abc
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence
    from importlib.machinery import ModuleSpec
    from types import ModuleType

# robomimic package -> our module that registers into it once it is imported
REGISTERING_MODULES = {
    "robomimic.config": "veragmil_suite.learning.algos.diffusion_policy_config",
    "robomimic.algo": "veragmil_suite.learning.algos.diffusion_policy",
}


class _ImportAfter(importlib.abc.Loader):
    """A package's own loader that imports ``then`` once the package has executed."""

    def __init__(self, loader, then: str):
        self._loader = loader
        self._then = then

    def create_module(self, spec: ModuleSpec) -> ModuleType | None:
        return self._loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        self._loader.exec_module(module)
        importlib.import_module(self._then)

    def __getattr__(self, name):  # get_source, get_resource_reader, is_package, ...: the package's own loader's
        return getattr(self._loader, name)


class _RegisterAfterImport(importlib.abc.MetaPathFinder):
    """Finds robomimic's registry packages as the other finders would, with a loader that registers ours after."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> ModuleSpec | None:
        then = REGISTERING_MODULES.get(fullname)
        if then is None:
            return None
        for finder in sys.meta_path:
            find_spec = getattr(finder, "find_spec", None) if finder is not self else None
            spec = find_spec(fullname, path, target) if find_spec is not None else None
            if spec is not None:
                if spec.loader is not None:
                    spec.loader = _ImportAfter(spec.loader, then)
                return spec
        return None


def register_on_import() -> None:
    """Registers our algorithms with robomimic now if it is imported, else as soon as it is (idempotent)."""
    if not any(isinstance(finder, _RegisterAfterImport) for finder in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterImport())
    for package, module in REGISTERING_MODULES.items():
        if package in sys.modules:
            importlib.import_module(module)
