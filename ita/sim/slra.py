"""The SLRA's physics: an amplitude-modulated, raster-scanned laser range image.

    scene = SlraScene.from_truth(part_dir, workcell)          # once: as-built part + cell boxes
    frame = simulate_frame(scene, true_pose, ScanGeometry(), SlraParams(), rng,
                           reported_pose=commanded_pose, timestamp=t)

What is modelled, per pixel of the raster (see ita.sensors.slra_frame for the scan):

* the beam's first hit on the AS-BUILT part or a workcell box (embree ray casting, in the
  part frame, millimetres); holes are the as-built cylinders, not the mesh's polygons
  (whose chords would read a few hundredths small), and a bore wall seen within ~6 deg of
  grazing returns nothing, so the beam's share goes on to what lies beyond;
* return amplitude A = rho cos(theta) (R_ref / R)^2 (diffuse machined 7075);
* mixed pixels: the beam footprint is a Gaussian of sigma_b(R) = waist + R * divergence;
  where it straddles a depth step (found between neighbouring pixels, then located by
  bisecting the scan angle; a third surface between the two, such as a bore's wall below
  a rim, goes with the farther side, so the step lies at the near surface's edge) the return is the phasor sum of the two surfaces' returns,
  weighted by the share of the footprint on each (half-plane model of the edge; the other
  surface is sampled at the pixel's mirror image across the edge);
* range from phase: phi = 4 pi f R / c plus phase noise sigma_phi = sigma_phi_ref
  (A_ref / A)^gamma, wrapped to [0, 2 pi): ranges beyond the ambiguity interval c / 2f wrap
  around; sigma_R = c sigma_phi / (4 pi f), so noise grows with distance, incidence and
  darker surfaces;
* dropouts: returns below the detection threshold, and specular loss that rises to all
  pixels as incidence approaches grazing, plus a small random rate;
* an intensity image (the measured amplitude) and a frame time from the pixel rate and the
  line flyback.

The scene is built once (one embree-backed intersector over the part and every box) and
reused for every frame; everything per frame is vectorised.  Randomness comes only from
the Generator passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import trimesh
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree
from scipy.special import ndtr

from ita.cores import SecondCore
from ita.part.model import Hole
from ita.part.store import load_part
from ita.sensors.slra_frame import (
    SPEED_OF_LIGHT,
    RangeFrame,
    ScanGeometry,
    rotate_directions,
)
from ita.sim.world import simulated_part
from ita.workcell.model import Box, PartPlacement, Workcell

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SlraParams:
    """Physics of one SLRA (defaults: a 50 MHz AM sensor looking at machined 7075).

    reference_range_m: where amplitude 1 is defined (the nominal standoff);
    reflectance: diffuse reflectance rho of the part (bead-blasted/machined Al ~0.5);
    box_reflectance: of the painted workcell boxes; sigma_phase_ref: phase noise (rad) at
    amplitude = reflectance (square-on at reference range); noise_exponent gamma: sigma_phi
    ~ A^-gamma (0.5: shot-noise limited); min_amplitude: detection threshold;
    grazing_start_deg/grazing_full_deg: specular loss begins / is total; dropout_rate: random
    dropouts elsewhere; beam_waist_m/beam_divergence_rad: footprint sigma_b(R) = waist +
    R * divergence; jump_m: depth step between neighbouring pixels taken as an edge (beyond
    the neighbour's plane); bisection_steps: how finely an edge is located;
    intensity_noise: relative; pixel_rate_hz/line_flyback_s: scan timing.
    """

    reference_range_m: float = 0.45
    reflectance: float = 0.55
    box_reflectance: float = 0.3
    sigma_phase_ref: float = 5e-4
    noise_exponent: float = 0.5
    min_amplitude: float = 0.01
    grazing_start_deg: float = 72.0
    grazing_full_deg: float = 86.0
    dropout_rate: float = 5e-4
    beam_waist_m: float = 0.1e-3
    beam_divergence_rad: float = 0.4e-3
    jump_m: float = 1.0e-3
    bisection_steps: int = 5
    intensity_noise: float = 0.01
    pixel_rate_hz: float = 200e3
    line_flyback_s: float = 0.5e-3

    def range_sigma(self, amplitude: FloatArray, modulation_hz: float) -> FloatArray:
        """Range noise (m) of returns of `amplitude` (any shape)."""
        return SPEED_OF_LIGHT / (4 * math.pi * modulation_hz) * self.phase_sigma(amplitude)

    def phase_sigma(self, amplitude: FloatArray) -> FloatArray:
        """Phase noise (rad) of returns of `amplitude`."""
        a = np.maximum(np.asarray(amplitude, dtype=float), 1e-9)
        return self.sigma_phase_ref * (self.reflectance / a) ** self.noise_exponent

    def frame_time(self, geometry: ScanGeometry) -> float:
        """Time (s) to scan one frame of `geometry`."""
        h, w = geometry.shape
        return h * (w / self.pixel_rate_hz + self.line_flyback_s)


MISS, PART, BOX = -1, 0, 1
GRAZING_WALL_COS = 0.1
HOLE_EXIT_MARGIN_MM = 1.0
SAME_SURFACE_COS = 0.9   # normals within ~25 deg: one surface, for locating a step between two
#: rays of one cast from which a second core takes half (embree and the compiled kernels run
#: without the GIL; below this, waking a thread costs about what it saves)
SPLIT_RAYS = 8192
#: points of one nearest-edge query (scipy's k-d tree, without the GIL) from which a second
#: core takes half
SPLIT_QUERIES = 1024


class Hits(NamedTuple):
    """First hits of n rays: distance (n,) mm (inf: none), surface normal (n, 3) and what
    was hit (n,): MISS, PART or BOX.  The arrays may be updated in place by their maker."""

    dist: FloatArray
    normals: FloatArray
    kind: NDArray[np.int64]


def _box_mesh_in_part(box: Box, placement: PartPlacement) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=np.asarray(box.size, dtype=float))
    m.apply_transform(box.pose.matrix())
    return trimesh.Trimesh(placement.to_part(np.asarray(m.vertices)), m.faces, process=False)


class SlraScene:
    """What the beam can hit, built once: the part mesh and boxes, in the part frame (mm).

    mesh_mm: the (as-built) part; boxes: world boxes (workcell, obstacles); holes: the
    part's holes along +Z whose rims are taken as exact circles (a mesh's holes are
    polygons, whose chords would read a few hundredths of a millimetre small).
    """

    def __init__(self, mesh_mm: trimesh.Trimesh, placement: PartPlacement,
                 boxes: Sequence[Box] = (), holes: Sequence[Hole] = ()):
        parts = [trimesh.Trimesh(np.asarray(mesh_mm.vertices), np.asarray(mesh_mm.faces), process=False)]
        parts += [_box_mesh_in_part(b, placement) for b in boxes]
        self.placement = placement
        self._made_of = (mesh_mm, tuple(boxes), tuple(holes))
        self.n_part_faces = len(mesh_mm.faces)
        mesh = trimesh.util.concatenate(parts)
        assert isinstance(mesh, trimesh.Trimesh)   # meshes concatenate to a mesh
        self.mesh = mesh
        self.normals = np.ascontiguousarray(mesh.face_normals, dtype=np.float64)
        self.anchor = np.ascontiguousarray(mesh.triangles[:, 0], dtype=np.float64)
        self.intersector = trimesh.ray.ray_pyembree.RayMeshIntersector(self.mesh)
        up = [h for h in holes if h.axis[2] > 0.999]
        self._hole_xy = np.ascontiguousarray(np.array([h.center[:2] for h in up], dtype=float).reshape(-1, 2))
        self._hole = np.ascontiguousarray(np.array([(h.center[2], h.diameter / 2, h.depth) for h in up]).reshape(-1, 3))
        self._near_hole = _hole_raster(self._hole_xy, self._hole[:, 1]) if up else None
        self.intersector.intersects_first(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))  # builds embree's scene now
        self.core = SecondCore(SPLIT_RAYS, "slra")       # casts and kernels split with a second core

    @classmethod
    def from_simulated(cls, simulated, workcell: Workcell, extra_boxes: Sequence[Box] = (),
                       placement: PartPlacement | None = None) -> SlraScene:
        """The simulated part (ita.sim.world.simulated_part) with every static box of
        `workcell`, the part where it really sits (`placement`; default: its nominal place)."""
        return cls(simulated.mesh, placement if placement is not None else workcell.part,
                   tuple(workcell.static_boxes()) + tuple(extra_boxes), simulated.holes)

    def placed(self, placement: PartPlacement) -> SlraScene:
        """The same scene with the part at `placement` (the boxes stay where they are)."""
        mesh_mm, boxes, holes = self._made_of
        return SlraScene(mesh_mm, placement, boxes, holes)

    @classmethod
    def from_truth(cls, part_dir: Path, workcell: Workcell, extra_boxes: Sequence[Box] = ()) -> SlraScene:
        """The part in `part_dir` as the simulator holds it (its as-built truth, else its
        as-built mesh, else its nominal mesh) with every static box of `workcell`."""
        part = load_part(part_dir)
        return cls.from_simulated(simulated_part(part.directory, part.mesh), workcell, extra_boxes)

    def directions(self, geometry: ScanGeometry) -> FloatArray:
        """Sensor-frame pixel directions (H*W, 3) of `geometry` (read-only; the geometry
        keeps its last few: a run's views have hundreds of windows, each used a few times)."""
        return geometry.directions().reshape(-1, 3)

    def cast(self, origin: FloatArray, dirs: FloatArray) -> Hits:
        """First hits of rays from part point `origin` (3,) mm along unit `dirs` (n, 3)."""
        return Hits(*self.core.in_halves(self._cast, (dirs,), origin))

    def _cast(self, dirs: FloatArray, origin: FloatArray) -> Hits:
        n = len(dirs)
        face = self.intersector.intersects_first(np.broadcast_to(origin, (n, 3)), dirs)
        hits = self._hits(np.broadcast_to(origin, (n, 3)), dirs, face)
        if self._near_hole is not None:
            self._into_holes(origin, dirs, hits)
        return hits

    def _hits(self, origins: FloatArray, dirs: FloatArray, face: NDArray[np.int64]) -> Hits:
        """The hits of rays (origins, dirs (n, 3)) on the faces embree found (-1: none): the
        distance to each face's plane in float64 (embree's own is float32), its normal, kind."""
        return Hits(*_hits_kernel(np.ascontiguousarray(origins), np.ascontiguousarray(dirs),
                                  np.ascontiguousarray(face, dtype=np.int64), self.normals, self.anchor,
                                  self.n_part_faces))

    def _into_holes(self, origin: FloatArray, dirs: FloatArray, hits: Hits) -> None:
        """Rays whose hit lies on or in a hole's true cylinder (entry face inside the
        circle, or the mesh's polygonal wall) go into the exact cylinder: they meet its wall
        where they reach the radius within the drilled depth, else go on below it (cast
        again from below the drilled material, with room for its thickness deviation: a
        hole's depth is nominal, and nothing lies within that of a cap's or web's back)."""
        assert self._near_hole is not None   # called only when the part has holes from above
        lo, cell, table = self._near_hole
        below, step = _holes_kernel(np.ascontiguousarray(origin, dtype=np.float64), np.ascontiguousarray(dirs),
                                    hits.dist, hits.normals, hits.kind, lo, cell, table, self._hole_xy, self._hole,
                                    GRAZING_WALL_COS, HOLE_EXIT_MARGIN_MM)
        if len(below):
            d = dirs[below]
            start = origin + step[:, None] * d
            more = self._hits(start, d, self.intersector.intersects_first(start, d))
            hits.dist[below] = step + more.dist
            hits.normals[below] = more.normals
            hits.kind[below] = more.kind


@njit(cache=True, nogil=True)
def _holes_kernel(origin, dirs, dist, normals, kind, lo, cell, table, hole_xy, hole, grazing_cos,
                  exit_margin):  # pragma: no cover - compiled
    """SlraScene._into_holes per ray: the wall hits are written into dist and normals; the
    rays that go on below a hole are returned (indices, and their distance to restart)."""
    n = len(dirs)
    below = np.empty(n, dtype=np.int64)
    step = np.empty(n)
    m = 0
    gx, gy, slots = table.shape
    for i in range(n):
        if kind[i] != PART:
            continue
        px = origin[0] + dist[i] * dirs[i, 0]
        py = origin[1] + dist[i] * dirs[i, 1]
        pz = origin[2] + dist[i] * dirs[i, 2]
        ci = np.int64(np.floor((px - lo[0]) / cell))
        cj = np.int64(np.floor((py - lo[1]) / cell))
        if ci < 0 or cj < 0 or ci >= gx or cj >= gy or table[ci, cj, 0] < 0:
            continue
        k = -1
        gap = np.inf
        for t in range(slots):          # the nearest of the holes near this cell
            h = table[ci, cj, t]
            if h < 0:
                break
            g = np.sqrt((px - hole_xy[h, 0]) ** 2 + (py - hole_xy[h, 1]) ** 2)
            if g < gap:
                gap, k = g, h
        cz, r, depth = hole[k, 0], hole[k, 1], hole[k, 2]
        d0, d1, d2 = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        if not (gap < r + 0.05 and pz < cz + 1e-3 and pz > cz - depth - 1e-3 and d2 < -1e-9):
            continue
        s0 = (cz - origin[2]) / d2                                   # to the entry plane
        c0 = origin[0] + s0 * d0 - hole_xy[k, 0]
        c1 = origin[1] + s0 * d1 - hole_xy[k, 1]
        cc = c0 ** 2 + c1 ** 2
        if not cc < r ** 2:
            continue
        a = d0 ** 2 + d1 ** 2
        b = c0 * d0 + c1 * d1
        s1 = (-b + np.sqrt(b * b - a * (cc - r ** 2))) / a            # out to the wall
        finite = np.isfinite(s1)
        f = s1 if finite else 0.0
        r0 = c0 + f * d0
        r1 = c1 + f * d1
        cos_wall = abs(r0 * d0 + r1 * d1) / r
        # a wall seen within ~6 deg of grazing returns nothing: its share goes beyond it
        if finite and -s1 * d2 < depth and cos_wall > grazing_cos:
            dist[i] = s0 + s1
            normals[i, 0] = -r0 / r
            normals[i, 1] = -r1 / r
            normals[i, 2] = 0.0
        else:
            below[m] = i
            step[m] = s0 + (depth + exit_margin) / -d2
            m += 1
    return below[:m].copy(), step[:m].copy()


@njit(cache=True, nogil=True)
def _hits_kernel(origins, dirs, face, face_normals, anchor, n_part_faces):  # pragma: no cover - compiled
    n = len(dirs)
    dist = np.full(n, np.inf)
    normals = np.zeros((n, 3))
    kind = np.full(n, MISS, dtype=np.int64)
    for i in range(n):
        f = face[i]
        if f < 0:
            continue
        num = 0.0
        den = 0.0
        for j in range(3):
            num += face_normals[f, j] * (anchor[f, j] - origins[i, j])
            den += face_normals[f, j] * dirs[i, j]
            normals[i, j] = face_normals[f, j]
        dist[i] = num / den
        kind[i] = PART if f < n_part_faces else BOX
    return dist, normals, kind


def _hole_raster(xy: FloatArray, radius: FloatArray, cell: float = 1.0) -> tuple[FloatArray, float, NDArray[np.int64]]:
    """A coarse raster over the holes' XY box: for each cell, the holes (indices, -1 after
    the last) it may lie within 0.2 mm of the circle of (a cheap first test before the
    exact one)."""
    lo = (xy - radius[:, None]).min(axis=0) - 2 * cell
    hi = (xy + radius[:, None]).max(axis=0) + 2 * cell
    shape = np.ceil((hi - lo) / cell).astype(int)
    count = np.zeros(shape, dtype=np.int64)
    marks = []
    for k, ((x, y), r) in enumerate(zip(xy, radius)):
        i0, j0 = np.floor((np.array([x, y]) - r - 1 - lo) / cell).astype(int)
        i1, j1 = np.ceil((np.array([x, y]) + r + 1 - lo) / cell).astype(int)
        ci = lo[0] + (np.arange(i0, i1) + 0.5) * cell
        cj = lo[1] + (np.arange(j0, j1) + 0.5) * cell
        ii, jj = np.nonzero(np.hypot(ci[:, None] - x, cj[None, :] - y) < r + 0.2 + cell)
        marks.append((ii + i0, jj + j0, k))
        count[ii + i0, jj + j0] += 1
    table = np.full((*shape, max(int(count.max()), 1)), -1, dtype=np.int64)
    filled = np.zeros(shape, dtype=np.int64)
    for ii, jj, k in marks:
        table[ii, jj, filled[ii, jj]] = k
        filled[ii, jj] += 1
    return lo, cell, table


def pose_error(pose: FloatArray, rng: np.random.Generator, translation_sigma_m: float,
               rotation_sigma_rad: float = 0.0) -> FloatArray:
    """`pose` (4, 4) moved by a random arm error: normal translation and small rotation."""
    out = np.array(pose, dtype=float)
    w = rng.normal(0.0, rotation_sigma_rad, 3)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    out[:3, :3] = (np.eye(3) + k + k @ k / 2) @ out[:3, :3]
    u, _, vt = np.linalg.svd(out[:3, :3])
    out[:3, :3] = u @ vt
    out[:3, 3] += rng.normal(0.0, translation_sigma_m, 3)
    return out


def _plane_range(normal: FloatArray, point: FloatArray, origin: FloatArray, dirs: FloatArray) -> FloatArray:
    """Range (n,) along dirs (n, 3) from origin to the planes (point, normal) (n, 3)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.einsum("ij,ij->i", normal, point - origin) / np.einsum("ij,ij->i", normal, dirs)


def simulate_frame(scene: SlraScene, pose: FloatArray, geometry: ScanGeometry, params: SlraParams,
                   rng: np.random.Generator, *, reported_pose: FloatArray | None = None,
                   timestamp: float = 0.0, sensor: str = "slra") -> RangeFrame:
    """One range frame taken from the TRUE sensor pose `pose` (4, 4, world, m).

    reported_pose: the pose the robot reports (stamped on the frame; default `pose`).
    """
    pl = scene.placement
    h, w = geometry.shape
    rot = pl.rotation_matrix()
    origin = pl.to_part(np.asarray(pose, dtype=float)[None, :3, 3])[0]
    to_part = rot.T @ np.asarray(pose, dtype=float)[:3, :3]            # sensor -> part directions

    def cast_sensor(d_sensor: FloatArray) -> tuple[Hits, FloatArray]:
        d = rotate_directions(d_sensor, to_part)
        return scene.cast(origin, d), d

    hits, dirs = cast_sensor(scene.directions(geometry))
    # the frame's noise, drawn (without the GIL) on the second core while this one finds the mixed pixels
    draws = scene.core.beside(lambda: (rng.random(h * w), rng.normal(0.0, 1.0, h * w), rng.normal(0.0, 1.0, h * w)))
    amp, p_drop = _returns(params, hits, dirs, pl.scale)
    frac, other_r, other_amp, other_drop = _mix(geometry, params, cast_sensor, origin, dirs, hits, pl.scale,
                                                 scene.core)

    k = 4 * math.pi * geometry.modulation_hz / SPEED_OF_LIGHT * pl.scale   # rad per mm
    n_rows = (hits.kind != MISS, hits.dist, amp, p_drop, frac, other_r, other_amp, other_drop, *draws.result())
    rng_m, inten = scene.core.in_halves(_phase_kernel, n_rows, k, params.min_amplitude, params.sigma_phase_ref,
                                        params.reflectance, params.noise_exponent, params.intensity_noise,
                                        geometry.ambiguity_m)
    return RangeFrame(rng_m.reshape(h, w), inten.reshape(h, w),
                      np.asarray(pose if reported_pose is None else reported_pose, dtype=float),
                      geometry, timestamp, params.frame_time(geometry), sensor)


@njit(cache=True, nogil=True)
def _phase_kernel(hit, dist, amp, p_drop, frac, other_r, other_amp, other_drop, u_drop, n_phase, n_inten, k,
                  min_amplitude, sigma_ref, reflectance, exponent, intensity_noise, ambiguity_m
                  ):  # pragma: no cover - compiled
    """Per pixel: the phasor sum of its own return and the mixed-in other surface's, its
    dropout (below the least amplitude, or drawn: u_drop < the returns' mixed dropout
    probability), phase noise (n_phase standard normal draws times SlraParams.phase_sigma),
    the wrapped range (m; nan when dropped) and the intensity (n_inten draws)."""
    n = dist.shape[0]
    out_r = np.empty(n)
    out_i = np.empty(n)
    two_pi = 2 * math.pi
    for i in range(n):
        own = dist[i] if hit[i] else 0.0
        f = frac[i]
        a1 = (1 - f) * amp[i]
        re = a1 * math.cos(k * own)
        im = a1 * math.sin(k * own)
        if f > 0.0:                  # a mixed pixel (most are not: their other term is an exact 0)
            a2 = f * other_amp[i]
            re += a2 * math.cos(k * other_r[i])
            im += a2 * math.sin(k * other_r[i])
        a = math.hypot(re, im)
        sigma = sigma_ref * (reflectance / max(a, 1e-9)) ** exponent
        phase = math.atan2(im, re) + n_phase[i] * sigma
        if a < min_amplitude or u_drop[i] < (1 - f) * p_drop[i] + f * other_drop[i]:
            out_r[i] = np.nan
        else:
            out_r[i] = (phase % two_pi) / two_pi * ambiguity_m
        out_i[i] = 0.0 if a < min_amplitude else max(a * (1 + intensity_noise * n_inten[i]), 0.0)
    return out_r, out_i


def _returns(params: SlraParams, hits: Hits, dirs: FloatArray, scale: float) -> tuple[FloatArray, FloatArray]:
    """Amplitude (n,) of the returns of rays with `hits` along dirs (n, 3), and their
    dropout probability (n,) (specular loss toward grazing incidence); scale: m per mm."""
    hit = hits.kind != MISS
    cos_inc = np.abs(np.einsum("ij,ij->i", hits.normals, dirs))
    refl = np.where(hits.kind == BOX, params.box_reflectance, params.reflectance)
    r_ref_mm = params.reference_range_m / scale
    with np.errstate(divide="ignore", invalid="ignore"):
        amp = np.where(hit, refl * cos_inc * (r_ref_mm / hits.dist) ** 2, 0.0)
    theta = np.degrees(np.arccos(np.clip(cos_inc, 0.0, 1.0)))
    spec = np.clip((theta - params.grazing_start_deg) / (params.grazing_full_deg - params.grazing_start_deg), 0, 1)
    p_drop = np.where(hit, params.dropout_rate + (1 - params.dropout_rate) * spec ** 2, params.dropout_rate)
    return amp, p_drop


def _mix(geometry: ScanGeometry, params: SlraParams, cast_sensor, origin: FloatArray, dirs: FloatArray,
         hits: Hits, scale: float, core: SecondCore) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Mixed pixels: for every pixel (flat), the share of its footprint beyond a depth step,
    and that other surface's range (mm), amplitude and dropout probability.

    Steps are found between neighbouring pixels (a neighbour off the pixel's plane by more
    than `jump_m`, or a hit beside a miss), located by bisecting the scan angle between
    them, and a pixel near one sees the other surface by sampling it at the pixel's mirror
    image across the edge."""
    h, w = geometry.shape
    n = h * w
    frac, other_r, other_amp, other_drop = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    thr = params.jump_m / scale
    hit, dist, normals = hits.kind != MISS, hits.dist, hits.normals
    pts = origin + np.where(hit, dist, 0.0)[:, None] * dirs
    p, q = _step_pairs(hit, dist, normals, pts, np.ascontiguousarray(origin, dtype=float), dirs, h, w, thr)
    if not len(p):
        return frac, other_r, other_amp, other_drop
    rc_p = np.column_stack(np.divmod(p, w)).astype(float)
    rc_q = np.column_stack(np.divmod(q, w)).astype(float)
    lo, hi = np.zeros(len(p)), np.ones(len(p))
    hp, hq = hit[p], hit[q]
    for _ in range(params.bisection_steps):
        t = (lo + hi) / 2
        rc = rc_p + t[:, None] * (rc_q - rc_p)
        mid, dd = cast_sensor(geometry.directions_at(rc[:, 0], rc[:, 1]))
        dm, hm = mid.dist, mid.kind != MISS
        with np.errstate(invalid="ignore"):
            ep = np.where(hp & hm, np.abs(dm - _plane_range(normals[p], pts[p], origin, dd)), np.inf)
            eq = np.where(hq & hm, np.abs(dm - _plane_range(normals[q], pts[q], origin, dd)), np.inf)
        # the mid ray is on p's surface when near p's plane AND facing the same way: a third
        # surface between them (a bore's wall below a rim) belongs to neither, and goes
        # with the farther side (what lies beyond the near surface's edge; a miss is farthest)
        like_p = hp & hm & (ep < 5 * thr) & _aligned(mid.normals, normals[p])
        like_q = hq & hm & (eq < 5 * thr) & _aligned(mid.normals, normals[q])
        p_far = np.where(hp, dist[p], np.inf) > np.where(hq, dist[q], np.inf)
        p_like = np.where(like_p & like_q, ep <= eq, np.where(like_p | like_q, like_p, p_far))
        lo, hi = np.where(p_like, t, lo), np.where(p_like, hi, t)
    t = (lo + hi) / 2
    ang = np.column_stack(geometry.angles(rc_p[:, 0] + t * (rc_q[:, 0] - rc_p[:, 0]),
                                          rc_p[:, 1] + t * (rc_q[:, 1] - rc_p[:, 1])))
    # footprint sigma, as an angle, at the nearer surface of each step
    r_step = np.minimum(np.where(hp, dist[p], np.inf), np.where(hq, dist[q], np.inf)) * scale
    sig = (params.beam_waist_m + r_step * params.beam_divergence_rad) / r_step
    da, de = geometry.pitch_rad
    reach = int(min(40, math.ceil(3.5 * sig.max() / min(da, de)) + 1))
    seed = np.zeros(n, dtype=bool)
    seed[p] = seed[q] = True
    x = np.flatnonzero(ndimage.maximum_filter(seed.reshape(h, w), size=2 * reach + 1).ravel())
    xang = np.column_stack(geometry.angles(*np.divmod(x, w)))
    d, toward, j = _edge_distance(ang, xang, min(da, de), core)
    f = ndtr(-d / sig[j])
    keep = f > 1e-4
    x, xang, d, toward, f = x[keep], xang[keep], d[keep], toward[keep], f[keep]
    mirror = xang + (2 * d + 0.5 * min(da, de))[:, None] * toward
    far, dd = cast_sensor(geometry.directions_at(mirror[:, 1] / de + h / 2 - 0.5, mirror[:, 0] / da + w / 2 - 0.5))
    am, pm = _returns(params, far, dd, scale)
    dm, hm = far.dist, far.kind != MISS
    with np.errstate(invalid="ignore"):
        same = (hm == hit[x]) & (~hm | ((np.abs(dm - dist[x]) < thr) & _aligned(far.normals, normals[x])))
    f = np.where(same, 0.0, f)
    frac[x], other_r[x], other_amp[x], other_drop[x] = f, np.where(hm, dm, 0.0), am, pm
    return frac, other_r, other_amp, other_drop


@njit(cache=True, error_model="numpy")
def _step_pairs(hit, dist, normals, pts, origin, dirs, h, w, thr):  # pragma: no cover - compiled
    """The neighbouring pixel pairs (flat indices p, q; the horizontal pairs row by row, then
    the vertical ones) across a depth step: a hit beside a miss, or two hits each off the
    other's plane by more than thr along its own ray (pairs whose ranges differ by 0.2 thr
    or less are not looked at)."""
    n = 2 * h * w
    out_p = np.empty(n, dtype=np.int64)
    out_q = np.empty(n, dtype=np.int64)
    m = 0
    near = 0.2 * thr
    for vertical in range(2):
        for r in range(h - vertical):
            for c in range(w - 1 + vertical):
                i = r * w + c
                j = i + w if vertical else i + 1
                if hit[i] != hit[j]:
                    out_p[m], out_q[m] = i, j
                    m += 1
                    continue
                if not (hit[i] and abs(dist[i] - dist[j]) > near):
                    continue
                # range along j's ray to i's plane, and along i's ray to j's plane
                num = (normals[i, 0] * (pts[i, 0] - origin[0]) + normals[i, 1] * (pts[i, 1] - origin[1])) \
                    + normals[i, 2] * (pts[i, 2] - origin[2])
                den = (normals[i, 0] * dirs[j, 0] + normals[i, 1] * dirs[j, 1]) + normals[i, 2] * dirs[j, 2]
                rj = num / den
                num = (normals[j, 0] * (pts[j, 0] - origin[0]) + normals[j, 1] * (pts[j, 1] - origin[1])) \
                    + normals[j, 2] * (pts[j, 2] - origin[2])
                den = (normals[j, 0] * dirs[i, 0] + normals[j, 1] * dirs[i, 1]) + normals[j, 2] * dirs[i, 2]
                ri = num / den
                if abs(dist[j] - rj) > thr and abs(dist[i] - ri) > thr:
                    out_p[m], out_q[m] = i, j
                    m += 1
    return out_p[:m], out_q[:m]


def _aligned(a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
    """(n,) whether unit normals a, b (n, 3) face the same way within about 25 deg."""
    return np.abs(np.einsum("ij,ij->i", a, b)) > SAME_SURFACE_COS


def _edge_distance(edges: FloatArray, x: FloatArray, pitch: float, core: SecondCore
                   ) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Distance (n,) of points x (n, 2) to the edge through the points `edges` (m, 2), the
    unit direction (n, 2) from each point toward the edge, and the index (n,) of the
    nearest edge point.  The distance is to a line fitted to the 4 nearest edge points (to
    the nearest one alone where those do not spread along a line)."""
    k = min(4, len(edges))
    tree = cKDTree(edges)
    dd, ii = core.in_halves(lambda half: tree.query(half, k=k), (x,), min_rows=SPLIT_QUERIES)
    dd, ii = dd.reshape(len(x), k), ii.reshape(len(x), k)
    if k < 2:
        e1 = edges[ii[:, 0]] - x
        return dd[:, 0], e1 / np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-15), ii[:, 0]
    d, toward = _edge_line_kernel(np.ascontiguousarray(edges, dtype=np.float64), np.ascontiguousarray(ii),
                                  np.ascontiguousarray(dd[:, 0]), np.ascontiguousarray(x, dtype=np.float64),
                                  float(pitch))
    return d, toward, ii[:, 0]


@njit(cache=True)
def _edge_line_kernel(edges, ii, d1, x, pitch):  # pragma: no cover - compiled
    """Per point of x (n, 2): the distance to the line through its k nearest edge points
    (edges[ii[i]]; their principal direction) and the unit direction toward it, or, where
    those points do not spread along a line, the distance d1 to the nearest one and the
    direction toward it (see _edge_distance)."""
    n, k = ii.shape
    dist = np.empty(n)
    toward = np.empty((n, 2))
    for i in range(n):
        x0, y0 = x[i, 0], x[i, 1]
        ex, ey = edges[ii[i, 0], 0] - x0, edges[ii[i, 0], 1] - y0
        norm = max(math.sqrt(ex * ex + ey * ey), 1e-15)
        mx = my = 0.0
        for j in range(k):
            mx += edges[ii[i, j], 0]
            my += edges[ii[i, j], 1]
        mx /= k
        my /= k
        sxx = syy = sxy = 0.0
        for j in range(k):
            cx, cy = edges[ii[i, j], 0] - mx, edges[ii[i, j], 1] - my
            sxx += cx * cx
            syy += cy * cy
            sxy += cx * cy
        ang = 0.5 * math.atan2(2 * sxy, sxx - syy)            # principal direction
        ux, uy = math.cos(ang), math.sin(ang)
        along = across = 0.0
        for j in range(k):
            cx, cy = edges[ii[i, j], 0] - mx, edges[ii[i, j], 1] - my
            along = max(along, abs(cx * ux + cy * uy))
            across = max(across, abs(-cx * uy + cy * ux))
        if along > 0.3 * pitch and across < 0.25 * along:
            off = (mx - x0) * -uy + (my - y0) * ux
            s = -1.0 if off < 0 else 1.0
            dist[i], toward[i, 0], toward[i, 1] = abs(off), -uy * s, ux * s
        else:
            dist[i], toward[i, 0], toward[i, 1] = d1[i], ex / norm, ey / norm
    return dist, toward
