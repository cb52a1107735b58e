"""Reading a part's mesh file (STL, OBJ or PLY, millimetres): damage named, and triangles
with NaN or infinite coordinates counted.

trimesh drops a triangle with a NaN or infinite vertex coordinate while it loads, without
a word; :func:`read_mesh` counts them in the file first and says how many were dropped
(a MeshWarning: `warning: FILE: ...` on the command line), or refuses the file when no
triangle is left.  Every refusal is an InputError naming the file (exit code 2).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import trimesh

from ita.errors import InputError, ItaWarning, Location

__all__ = ["MeshWarning", "nonfinite_triangles", "read_mesh", "stl_problem"]

#: one triangle of a binary STL: normal, three vertices, attribute bytes (50 bytes)
_STL_TRIANGLE = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])


class MeshWarning(ItaWarning):
    """Something about a mesh file that the reader mended (triangles dropped)."""


def stl_problem(path: Path) -> str:
    """Why `path`, an STL file, is neither a whole binary STL nor ASCII; "" when it may be."""
    if path.suffix.lower() != ".stl":
        return ""
    try:
        size = path.stat().st_size
        with open(path, "rb") as handle:
            head = handle.read(84)
    except OSError as exc:
        return exc.strerror or str(exc)
    if head.lstrip().lower().startswith(b"solid"):
        return ""  # ASCII STL (or a binary one whose header says solid: trimesh decides)
    if size < 84:
        return f"not an STL file: {size} bytes, shorter than a binary STL header"
    count = int.from_bytes(head[80:84], "little")
    if size != 84 + 50 * count:
        return (f"damaged binary STL: the header announces {count} triangles ({84 + 50 * count} bytes) "
                f"but the file has {size} bytes")
    return ""


def nonfinite_triangles(path: Path) -> tuple[int, int]:
    """(triangles with a NaN or infinite vertex coordinate, triangles) of the mesh file as
    written, before any processing: a binary STL read directly, any other file by trimesh
    unprocessed."""
    path = Path(path)
    if path.suffix.lower() == ".stl":
        data = path.read_bytes()
        count = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
        if len(data) == 84 + 50 * count:
            vertices = np.frombuffer(data, dtype=_STL_TRIANGLE, count=count, offset=84)["vertices"]
            return int((~np.isfinite(vertices)).any(axis=(1, 2)).sum()), count
    raw = trimesh.load(path, force="mesh", process=False)
    vertices = np.asarray(getattr(raw, "vertices", np.zeros((0, 3))), dtype=float).reshape(-1, 3)
    faces = np.asarray(getattr(raw, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        return 0, 0
    bad = ~np.isfinite(vertices).all(axis=1)
    return int(bad[faces].any(axis=1).sum()), len(faces)


def read_mesh(path: Path, what: str = "mesh") -> trimesh.Trimesh:
    """The mesh in `path`, processed as trimesh loads it; `what` names it in messages.

    InputError for a damaged or unreadable file and for one without a triangle left; a
    MeshWarning saying how many triangles were dropped for NaN or infinite coordinates."""
    path = Path(path)
    problem = stl_problem(path)
    if problem:
        raise InputError([(Location(str(path)), f"cannot read {what}: {problem}")])
    try:
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # NaN corners: counted, not warned
            dropped, total = nonfinite_triangles(path)
            mesh = trimesh.load_mesh(path)
    except ImportError:  # trimesh guessing a text encoding of a damaged file
        raise InputError([(Location(str(path)), f"cannot read {what}: the file is damaged or not a mesh "
                                                f"of its type")]) from None
    except Exception as exc:  # trimesh raises many kinds on bad files
        raise InputError([(Location(str(path)), f"cannot read {what}: {exc}")]) from None
    faces = len(getattr(mesh, "faces", ()))
    if faces == 0:
        why = f": all {total} have a vertex with NaN or infinite coordinates" if dropped else ""
        raise InputError([(Location(str(path)), f"{what} has no triangles{why}")])
    if dropped:
        warnings.warn(f"{path}: dropped {dropped} of {total} triangles, each with a vertex with NaN or infinite "
                      f"coordinates ({faces} left)", MeshWarning, stacklevel=2)
    return mesh
