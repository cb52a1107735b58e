"""Planar region extraction over a whole range image.

Surface normals from the point image, jump and crease edges between neighbouring pixels;
the pixels left are grouped into 4-connected regions, and each region large enough gets a
plane fit.  The seed's "planar region extraction ... from laser scanner range data".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ita.sensors.slra_frame import RangeFrame
from ita.vision import edges

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PlanarRegion:
    """A planar region: its label in the label image, pixel count, unit normal (sensor
    frame, toward the sensor), offset d of n . p = d (m), RMS residual (m) and centroid."""

    label: int
    pixels: int
    normal: tuple[float, float, float]
    offset: float
    rms: float
    centroid: tuple[float, float, float]


def planar_regions(frame: RangeFrame, jump_m: float = 2e-3, crease_deg: float = 20.0,
                   min_pixels: int = 50, smooth_px: int = 5, inlier_m: float = 1e-3,
                   seed: int = 0) -> tuple[NDArray[np.int32], list[PlanarRegion]]:
    """Label image (H, W) (0: no region) and the planar regions of `frame`, largest first.

    Normals come from the range image smoothed over smooth_px x smooth_px pixels (range
    noise would otherwise turn every pixel into a crease).  The smoothing lets the mixed
    pixels of a depth step join a region's rim, so each region keeps only the inliers
    (within inlier_m) of its RANSAC plane."""
    rng = np.random.default_rng(seed)
    pts = frame.points()
    smooth = frame.geometry.directions() * edges.smooth_range(frame.range_m, smooth_px)[..., None]
    nrm = edges.normals(smooth, step=max(1, smooth_px // 2))
    split = edges.jump_edges(frame.range_m, jump_m) | edges.crease_edges(nrm, crease_deg)
    labels, count = ndimage.label(frame.valid & ~split & np.all(np.isfinite(nrm), axis=-1))
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    keep = np.flatnonzero(sizes >= min_pixels)
    keep = keep[keep > 0]
    keep = keep[np.argsort(-sizes[keep])]
    out_labels = np.zeros(labels.shape, dtype=np.int32)
    regions = []
    for new, old in enumerate(keep, start=1):
        mask = labels == old
        inlier = _ransac_plane(pts[mask], inlier_m, rng)
        if inlier.sum() < min_pixels:
            continue
        mask[mask] = inlier
        p = pts[mask]
        c = p.mean(axis=0)
        _, _, vt = np.linalg.svd(p - c, full_matrices=False)
        n = vt[2] if vt[2][2] < 0 else -vt[2]          # toward the sensor (it looks along +z)
        r = (p - c) @ n
        out_labels[mask] = new
        regions.append(PlanarRegion(new, int(mask.sum()), (float(n[0]), float(n[1]), float(n[2])), float(n @ c),
                                    float(np.sqrt(np.mean(r ** 2))), (float(c[0]), float(c[1]), float(c[2]))))
    return out_labels, regions


def _ransac_plane(p: FloatArray, inlier_m: float, rng: np.random.Generator, trials: int = 64) -> NDArray[np.bool_]:
    """(n,) bool: the points (n, 3) within inlier_m of the plane through 3 of them that
    has the most such points."""
    n = len(p)
    idx = rng.integers(0, n, size=(trials, 3))
    a, b, c = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
    nrm = np.cross(b - a, c - a)
    ln = np.linalg.norm(nrm, axis=1)
    ok = ln > 1e-12
    nrm, a = nrm[ok] / ln[ok, None], a[ok]
    if not len(nrm):
        return np.ones(n, dtype=bool)
    dist = np.abs((p[None, :, :] - a[:, None, :]) @ nrm[:, :, None])[..., 0] if n * len(nrm) < 4e6 else None
    if dist is None:
        sub = rng.choice(n, size=int(4e6 // len(nrm)), replace=False)
        best = int(np.argmax((np.abs((p[None, sub] - a[:, None]) @ nrm[:, :, None])[..., 0] < inlier_m).sum(1)))
    else:
        best = int(np.argmax((dist < inlier_m).sum(1)))
    return np.abs((p - a[best]) @ nrm[best]) < inlier_m
