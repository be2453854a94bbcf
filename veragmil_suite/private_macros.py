"""
robosuite's and robomimic's private macros files (``macros_private.py``), as this project sets them.

Both packages read a private macros file beside their ``macros.py`` when they are imported, and warn in every
process (each evaluation worker, each training run) when there is none; their ``scripts/setup_macros.py`` makes one
by copying ``macros.py``, to be edited. ``python -m veragmil_suite.private_macros`` (run by ``make setup``) writes
each one that is missing with only the macros set here, every other macro keeping its default: robosuite's console
log at WARNING, so its INFO line per controller loaded no longer interleaves with progress bars. A private macros
file that exists is left as it is, whoever wrote it.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from veragmil_suite.utils.whole_files import write_text_whole

# macro name -> value, per package; the rest keep the package's defaults
PRIVATE_MACROS: dict[str, dict[str, object]] = {
    "robosuite": {"CONSOLE_LOGGING_LEVEL": "WARNING"},
    "robomimic": {},
}
PRIVATE_MACROS_FILE = "macros_private.py"


def package_dir(package: str) -> Path:
    """An installed package's folder."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError(f"{package} is not installed")
    return Path(list(spec.submodule_search_locations)[0])


def private_macros_text(package: str, macros: dict[str, object]) -> str:
    """The private macros file of ``package`` that sets ``macros``."""
    lines = [
        f'"""Private macros of {package}, written by veragmil_suite.private_macros: the defaults of',
        f"{package}/macros.py, except those set here.",
        '"""',
        "",
    ]
    lines += [f"{name} = {value!r}" for name, value in macros.items()]
    return "\n".join(lines) + "\n"


def write_private_macros(folder: Path, package: str, macros: dict[str, object]) -> Path | None:
    """Writes ``folder``/macros_private.py unless one exists; returns its path, or None when it was there."""
    path = Path(folder) / PRIVATE_MACROS_FILE
    if path.exists():
        return None
    write_text_whole(path, private_macros_text(package, macros))
    return path


def missing_private_macros() -> list[str]:
    """The packages of PRIVATE_MACROS whose private macros file is missing."""
    return [p for p in PRIVATE_MACROS if not (package_dir(p) / PRIVATE_MACROS_FILE).exists()]


def main() -> int:
    """Writes every missing private macros file and says which it wrote."""
    for package, macros in PRIVATE_MACROS.items():
        written = write_private_macros(package_dir(package), package, macros)
        if written is not None:
            print(f"wrote {written}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
