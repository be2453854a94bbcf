"""One text per JSON-like value (keys sorted, anything else as its str): how two settings are compared and keyed."""

from __future__ import annotations

import json


def canonical(value) -> str:
    return json.dumps(value, sort_keys=True, default=str)
