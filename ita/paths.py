"""Where ITA finds its resources and keeps its data.

Resources (`prolog/`, `kb/`, `bulkhead/`) sit at the top of a checkout; an installed wheel
carries them as `ita/_resources/<name>`.  Nothing here depends on the working directory.
"""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent

RESOURCE_NAMES = ("prolog", "kb", "bulkhead")


def resource_dir(name: str) -> Path:
    """Return the directory of resource `name` ("prolog", "kb" or "bulkhead").

    Looks inside the installed package first, then beside the package in a checkout.
    Raises FileNotFoundError when neither exists.
    """
    if name not in RESOURCE_NAMES:
        raise ValueError(f"unknown resource {name!r}; expected one of {RESOURCE_NAMES}")
    for candidate in (_PACKAGE_DIR / "_resources" / name, _PACKAGE_DIR.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        f"resource directory {name!r} not found in {_PACKAGE_DIR / '_resources'} "
        f"or {_PACKAGE_DIR.parent}; is the package installed correctly?"
    )


def ita_home() -> Path:
    """The user's ITA data directory: $ITA_HOME, else $XDG_DATA_HOME/ita, else ~/.local/share/ita.

    Holds materialized parts (the built-in bulkhead is generated there on first use), and
    later the runs archive.  Created on demand.
    """
    env = os.environ.get("ITA_HOME")
    if env:
        home = Path(env).expanduser()
    else:
        xdg = os.environ.get("XDG_DATA_HOME")
        base = Path(xdg).expanduser() if xdg else Path.home() / ".local" / "share"
        home = base / "ita"
    home.mkdir(parents=True, exist_ok=True)
    return home


#: the built-in part's name, and its directory's under ``ita_home()/parts``
BUILTIN_NAME = "bulkhead"


def builtin_dir() -> Path:
    """Where the built-in bulkhead is materialised: ``ita_home()/parts/bulkhead``
    (:func:`ita.part.store.ensure_builtin` makes it there)."""
    return ita_home() / "parts" / BUILTIN_NAME
