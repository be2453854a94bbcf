"""One text per JSON-like value (keys sorted, anything else as its str): how two settings are compared and keyed."""

from __future__ import annotations

import json
from typing import Any


def canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)
