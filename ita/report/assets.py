"""The scripts and the stylesheet the pages use, all shipped with the package.

plotly.js comes from the plotly wheel (its `package_data/plotly.min.js`); `ita.js` and
`ita.css` (this package's `assets/`) draw the views.  Nothing is fetched from a network.
"""

from __future__ import annotations

from functools import cache
from importlib import resources
from pathlib import Path

from ita.errors import ItaError


class MissingAsset(ItaError):
    """A script the pages need is not installed."""


def asset_path(name: str) -> Path:
    """The file of asset `name`: "plotly.min.js", "ita.js" or "ita.css"."""
    if name == "plotly.min.js":
        try:
            path = Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))
        except ModuleNotFoundError:
            raise MissingAsset("plotly is not installed (pip install plotly): the charts need its plotly.js") from None
    elif name in ("ita.js", "ita.css"):
        path = Path(str(resources.files("ita.report") / "assets" / name))
    else:
        raise MissingAsset(f"no asset {name!r}")
    if not path.is_file():
        raise MissingAsset(f"{path}: missing")
    return path


@cache
def asset_text(name: str) -> str:
    """The text of asset `name` (read once per process: the files do not change)."""
    return asset_path(name).read_text(encoding="utf-8")
