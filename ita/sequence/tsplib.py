"""Read TSPLIB95 files of type EUC_2D and build their distance matrix.

Only what is needed to check the sequence planner's ordering code against published
optima: a ``TYPE: TSP`` file with ``EDGE_WEIGHT_TYPE: EUC_2D`` and a
``NODE_COORD_SECTION``.  Distances follow TSPLIB's rule for EUC_2D,
``d(i, j) = nint(sqrt(dx**2 + dy**2))`` with ``nint(x) = floor(x + 0.5)``.

Anything else (another edge weight type, a missing dimension, a malformed coordinate
line) raises :class:`ita.errors.InputError` naming the file and line, and so does a
problem larger than :data:`MAX_NODES` (the dense distance matrix grows with the square
of the nodes: 100,000 nodes would need 149 GiB) or a coordinate beyond
:data:`MAX_COORD` in size (its squared distances would overflow).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ita.errors import InputError, Location

SUPPORTED_WEIGHT_TYPES = ("EUC_2D",)
# Header keywords that may appear and are ignored.
IGNORED_KEYWORDS = ("NAME", "COMMENT", "CAPACITY", "NODE_COORD_TYPE", "DISPLAY_DATA_TYPE")
#: the most nodes solved: the (n, n) distance matrix and its working copies stay under 1 GB
MAX_NODES = 5_000
#: the largest coordinate size accepted, so that squared distances stay finite and exact
MAX_COORD = 1e9


@dataclass(frozen=True)
class TsplibProblem:
    """A symmetric EUC_2D TSPLIB instance.

    ``coords`` is ``(n, 2) float``: row ``k`` holds the node whose TSPLIB id is ``k + 1``.
    """

    name: str
    comment: str
    edge_weight_type: str
    coords: np.ndarray
    path: str = ""

    @property
    def dimension(self) -> int:
        """Number of nodes."""
        return int(self.coords.shape[0])

    def matrix(self) -> np.ndarray:
        """The ``(n, n) float`` distance matrix by TSPLIB's rule for the weight type."""
        return euc_2d_matrix(self.coords)


def euc_2d_matrix(coords: np.ndarray) -> np.ndarray:
    """TSPLIB EUC_2D distances, ``nint(sqrt(dx^2 + dy^2))``.

    ``coords``: ``(n, 2) float``.  Returns ``(n, n) float64`` with integer values.
    """
    xy = np.asarray(coords, dtype=np.float64)
    dx = xy[:, None, 0] - xy[None, :, 0]
    dy = xy[:, None, 1] - xy[None, :, 1]
    return np.floor(np.hypot(dx, dy) + 0.5)


def read_tsplib(path: str | Path) -> TsplibProblem:
    """Read a TSPLIB file (``TYPE: TSP``, ``EDGE_WEIGHT_TYPE: EUC_2D``).

    Raises :class:`InputError` with file and line for an unreadable file, an unsupported
    type or weight type, or a malformed ``NODE_COORD_SECTION``.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError([(Location(str(path)), f"cannot read file: {exc.strerror}")]) from exc
    return parse_tsplib(text, str(path))


def parse_tsplib(text: str, source: str = "<string>") -> TsplibProblem:
    """Parse the text of a TSPLIB file; ``source`` names it in error messages."""
    header: dict[str, tuple[str, int]] = {}
    lines = text.splitlines()
    coords: dict[int, tuple[float, float]] = {}
    section_line = 0
    lineno = 0

    def fail(line: int, message: str) -> InputError:
        return InputError([(Location(source, line), message)])

    while lineno < len(lines):
        raw = lines[lineno]
        lineno += 1
        line = raw.strip()
        if not line:
            continue
        if line == "EOF":
            break
        if line.endswith("_SECTION") or line.split(":")[0].strip().endswith("_SECTION"):
            keyword = line.split(":")[0].strip()
            if keyword != "NODE_COORD_SECTION":
                raise fail(lineno, f"unsupported section {keyword} (only NODE_COORD_SECTION)")
            section_line = lineno
            lineno = _read_coords(lines, lineno, coords, source)
            continue
        if ":" not in line:
            raise fail(lineno, f"expected 'KEYWORD : value', got {line[:40]!r}")
        key, value = (part.strip() for part in line.split(":", 1))
        key = key.upper()
        header[key] = (value, lineno)
        if key == "DIMENSION" and value.isdigit() and int(value) > MAX_NODES:
            raise fail(lineno, f"DIMENSION {int(value):,} is more than the {MAX_NODES:,} nodes `ita sequence "
                               f"tsp` solves (its distance matrix grows with the square of the nodes)")
        if key == "TYPE" and value.upper() not in ("TSP",):
            raise fail(lineno, f"unsupported TYPE {value} (only TSP)")
        if key == "EDGE_WEIGHT_TYPE" and value.upper() not in SUPPORTED_WEIGHT_TYPES:
            raise fail(lineno, f"unsupported EDGE_WEIGHT_TYPE {value} (only EUC_2D)")
        if key not in IGNORED_KEYWORDS + ("TYPE", "EDGE_WEIGHT_TYPE", "DIMENSION"):
            raise fail(lineno, f"unsupported keyword {key}")

    if "EDGE_WEIGHT_TYPE" not in header:
        raise fail(0, "missing EDGE_WEIGHT_TYPE (only EUC_2D is supported)")
    if "DIMENSION" not in header:
        raise fail(0, "missing DIMENSION")
    dim_text, dim_line = header["DIMENSION"]
    try:
        dimension = int(dim_text)
    except ValueError:
        raise fail(dim_line, f"DIMENSION is not an integer: {dim_text!r}") from None
    if dimension < 1:
        raise fail(dim_line, f"DIMENSION must be at least 1, got {dimension}")
    if not section_line:
        raise fail(0, "missing NODE_COORD_SECTION")
    if len(coords) > MAX_NODES:
        raise fail(section_line, f"{len(coords):,} nodes is more than the {MAX_NODES:,} that can be solved")
    if len(coords) != dimension:
        raise fail(section_line, f"NODE_COORD_SECTION has {len(coords)} nodes, DIMENSION says {dimension}")
    missing = sorted(set(range(1, dimension + 1)) - set(coords))
    if missing:
        raise fail(section_line, f"node ids must be 1..{dimension}; missing {missing[:5]}")
    xy = np.array([coords[k] for k in range(1, dimension + 1)], dtype=np.float64)
    return TsplibProblem(
        name=header.get("NAME", ("", 0))[0],
        comment=header.get("COMMENT", ("", 0))[0],
        edge_weight_type=header["EDGE_WEIGHT_TYPE"][0].upper(),
        coords=xy,
        path=source,
    )


def _read_coords(lines: list[str], lineno: int, coords: dict[int, tuple[float, float]], source: str) -> int:
    """Read ``id x y`` lines from index ``lineno`` until a keyword, ``EOF`` or the end.

    Fills ``coords`` (id -> (x, y)); returns the index of the first line not consumed.
    """
    while lineno < len(lines):
        line = lines[lineno].strip()
        if not line:
            lineno += 1
            continue
        if line == "EOF" or line[0].isalpha():
            return lineno
        lineno += 1
        fields = line.split()
        where = Location(source, lineno)
        if len(fields) != 3:
            raise InputError([(where, f"expected 'id x y' (3 fields), got {len(fields)}: {line[:40]!r}")])
        try:
            node = int(fields[0])
        except ValueError:
            raise InputError([(where, f"node id is not an integer: {fields[0]!r}")]) from None
        try:
            x, y = float(fields[1]), float(fields[2])
        except ValueError:
            raise InputError([(where, f"coordinates are not numbers: {line[:40]!r}")]) from None
        if not (np.isfinite(x) and np.isfinite(y)):
            raise InputError([(where, "coordinates must be finite")])
        if abs(x) > MAX_COORD or abs(y) > MAX_COORD:
            raise InputError([(where, f"coordinate out of range: {line[:60]!r} (at most {MAX_COORD:g} in size)")])
        if node in coords:
            raise InputError([(where, f"duplicate node id {node}")])
        if node < 1:
            raise InputError([(where, f"node ids start at 1, got {node}")])
        coords[node] = (x, y)
    return lineno
