"""Registries of named entries that plugins extend by decorator, as robomimic registers its algorithms: the
operator profiles (veragmil_suite.devices.expert) and the study's algorithms (veragmil_suite.learning.algorithms)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

Entry = TypeVar("Entry")


class Registry(dict, Generic[Entry]):
    """Entries by their ``name``; a name registered twice is refused.

    ``register`` decorates a function that returns an entry (its docstring says what the entry is for), or takes an
    entry itself::

        @PROFILES.register
        def careful() -> OperatorProfile:
            \"\"\"A slower, steadier hand than the expert's.\"\"\"
            return OperatorProfile("careful", speed=0.7)
    """

    def __init__(self, kind: str, entry_type: type) -> None:
        super().__init__()
        self.kind = kind
        self.entry_type = entry_type

    def register(self, entry: Entry | Callable[[], Entry]) -> Entry | Callable[[], Entry]:
        """Adds an entry (given, or made by the decorated function) under its name; returns what it was given."""
        made = entry if isinstance(entry, self.entry_type) else entry()
        if not isinstance(made, self.entry_type):
            kind = self.entry_type.__name__
            raise TypeError(f"a {self.kind} registration must give an entry of type {kind}, got {made!r}")
        if made.name in self:
            raise ValueError(f"{self.kind} {made.name!r} is registered already")
        self[made.name] = made
        return entry
