"""Faces of a mesh part moved off nominal: the flat faces an as-built's thicknesses,
heights and widths come out of (ita.part.truth.perturbed_asbuilt).

    moved, statement = offset_faces(mesh, specs, rng, spread=0.25, out_of_tolerance=0.05)

Each spec of a face-valued kind names one flat face of the mesh: the face at its point
(thicknesses, heights) or, for a width, the side face the material ends on along its
direction.  Every such face (a trimesh facet: coplanar neighbouring triangles, or one
triangle) of at least MIN_FACE_MM2 moves along its normal by a normal draw of one sigma `spread` x the smallest
tolerance of the specs on it, clipped to 0.9 of it; a seeded `out_of_tolerance` share of
the faces that carry one feature's specs is pushed 1.15 to 1.6 tolerances off.  A face moves with all its vertices: the
faces beside it (walls meeting a floor at right angles) stretch and stay flat.  Several
specs on one face (the thickness points of one pocket floor) share its deviation, as a
pocket machined too deep would.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import trimesh

from ita.part.infer import MeshRays
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec

#: kinds whose value is the distance to one face the spec points at
AT_POINT = (K.WEB_THICKNESS, K.FLANGE_THICKNESS, K.FLANGE_HEIGHT, K.STIFFENER_HEIGHT)
#: kinds whose value ends on a side face along the spec's direction
ACROSS = (K.STIFFENER_WIDTH, K.FLANGE_WIDTH)
PROBE_MM = 1.0      # rays start this far off the face, or this far under a width's top
MIN_FACE_MM2 = 200.0   # smaller faces (a curved surface's strips) are not moved: a lone bump is no machining


def spec_faces(mesh: trimesh.Trimesh, specs: Sequence[MeasurementSpec]) -> dict[str, int]:
    """The triangle (index) of the face each face-valued spec names, by spec id (specs
    whose face the rays do not find are left out)."""
    at = [s for s in specs if s.kind in AT_POINT]
    across = [s for s in specs if s.kind in ACROSS and s.direction is not None]
    origins, dirs, ids = [], [], []
    for s in at:
        n = np.asarray(s.normal, dtype=float)
        origins.append(np.asarray(s.point, dtype=float) + PROBE_MM * n)
        dirs.append(-n)
        ids.append(s.id)
    for s in across:                  # from inside the material, out along the direction
        n = np.asarray(s.normal, dtype=float)
        origins.append(np.asarray(s.point, dtype=float) - PROBE_MM * n)
        dirs.append(np.asarray(s.direction, dtype=float))
        ids.append(s.id)
    if not ids:
        return {}
    _, face = MeshRays(mesh).hits(np.asarray(origins), np.asarray(dirs))
    return {sid: int(f) for sid, f in zip(ids, face) if f >= 0}


def offset_faces(mesh: trimesh.Trimesh, specs: Sequence[MeasurementSpec], rng: np.random.Generator,
                 spread: float, out_of_tolerance: float) -> tuple[trimesh.Trimesh, dict[str, Any]]:
    """The mesh with the specs' faces moved (see the module docstring) and the statement of
    what was done: per face, its specs, its outward normal and its offset (mm)."""
    by_id = {s.id: s for s in specs}
    found = spec_faces(mesh, specs)
    facet_of = np.arange(len(mesh.faces)) + len(mesh.facets)        # a lone triangle: its own face
    for k, tris in enumerate(mesh.facets):
        facet_of[tris] = k
    area = np.concatenate([np.asarray(mesh.facets_area, dtype=float), np.asarray(mesh.area_faces, dtype=float)])
    faces: dict[int, list[str]] = {}
    for sid in sorted(found):
        k = int(facet_of[found[sid]])
        if area[k] >= MIN_FACE_MM2:
            faces.setdefault(k, []).append(sid)
    keys = sorted(faces)
    tol = {k: min(min(abs(by_id[s].upper), abs(by_id[s].lower)) for s in faces[k]) for k in keys}
    offset = {k: float(np.clip(rng.normal(0.0, spread * tol[k]), -0.9 * tol[k], 0.9 * tol[k])) for k in keys}
    # pushed out of tolerance: faces of one feature only (the generator pushes features, and a
    # face shared by many, a flange's whole cap, would take all their values out at once)
    single = [k for k in keys if len({by_id[s].feature for s in faces[k]}) == 1]
    pushed = sorted(int(k) for k in rng.choice(single, size=int(round(out_of_tolerance * len(single))),
                                               replace=False)) if single else []
    for k in pushed:
        offset[k] = float(rng.choice([-1.0, 1.0]) * rng.uniform(1.15, 1.6) * tol[k])
    verts = np.array(mesh.vertices, dtype=float)
    move = np.zeros_like(verts)
    statement = {}
    for k in keys:
        tris = mesh.facets[k] if k < len(mesh.facets) else [k - len(mesh.facets)]
        normal = np.asarray(mesh.face_normals[tris[0]], dtype=float)
        move[np.unique(mesh.faces[tris])] += offset[k] * normal
        statement[f"face {k}"] = {"specs": faces[k], "normal": [round(float(x), 6) for x in normal],
                                  "offset_mm": round(offset[k], 6), "pushed_out_of_tolerance": k in pushed}
    moved = trimesh.Trimesh(verts + move, np.asarray(mesh.faces), process=False)
    return moved, statement
