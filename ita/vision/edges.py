"""Edges in range images: jump edges, crease edges, and sub-pixel edge points.

Jump edges are depth steps between neighbouring pixels (or a pixel beside a dropout);
crease edges are where the surface normal turns.  For measuring, an edge between a near
surface and what lies beyond it is located to a fraction of a pixel: every pixel gets the
share `s` of its beam footprint that lies beyond the edge (0 on the near surface, 1 beyond;
mixed pixels in between), and the edge is where `s` crosses one half.  `s` comes from the
range where the far side returns (a mixed pixel's range is the amplitude-weighted mean of
the two returns for steps much shorter than the ambiguity interval) and from the intensity
where it does not (a void, or a surface too far to mix in phase).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def normals(points: FloatArray, step: int = 1) -> FloatArray:
    """(H, W, 3) unit surface normals (nan where undefined) from the central differences,
    `step` pixels either side, of an (H, W, 3) point image."""
    p = np.asarray(points, dtype=float)
    k = int(step)
    du = np.full_like(p, np.nan)
    dv = np.full_like(p, np.nan)
    du[:, k:-k] = p[:, 2 * k:] - p[:, :-2 * k]
    dv[k:-k] = p[2 * k:] - p[:-2 * k]
    n = np.cross(du, dv)
    with np.errstate(invalid="ignore", divide="ignore"):
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n


def jump_edges(range_img: FloatArray, threshold: float) -> NDArray[np.bool_]:
    """(H, W) bool: pixels with a 4-neighbour whose range differs by more than `threshold`,
    or which border a dropout."""
    r = np.asarray(range_img, dtype=float)
    out = np.zeros(r.shape, dtype=bool)
    for a, b in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                 ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
        with np.errstate(invalid="ignore"):
            j = ~(np.abs(r[a] - r[b]) <= threshold)
        j &= np.isfinite(r[a]) | np.isfinite(r[b])
        out[a] |= j & np.isfinite(r[a])
        out[b] |= j & np.isfinite(r[b])
    return out


def crease_edges(normal_img: FloatArray, angle_deg: float) -> NDArray[np.bool_]:
    """(H, W) bool: pixels whose normal differs from a 4-neighbour's by more than angle_deg."""
    n = np.asarray(normal_img, dtype=float)
    cos = np.cos(np.radians(angle_deg))
    out = np.zeros(n.shape[:2], dtype=bool)
    for a, b in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                 ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
        with np.errstate(invalid="ignore"):
            c = (n[a] * n[b]).sum(-1) < cos
        out[a] |= c
        out[b] |= c
    return out


def far_share_from_range(r: FloatArray, r_near: FloatArray, r_far: FloatArray, amp_ratio: float) -> FloatArray:
    """Share s of each footprint beyond the edge from ranges: r (...) measured, r_near and
    r_far the two surfaces' ranges along the same rays, amp_ratio = A_far / A_near."""
    with np.errstate(invalid="ignore", divide="ignore"):
        est = np.clip((r - r_near) / (r_far - r_near), 0.0, 1.0)
        return est / (amp_ratio * (1 - est) + est)


def far_share_from_intensity(i: FloatArray, i_near: FloatArray) -> FloatArray:
    """Share s of each footprint beyond the edge when nothing returns from beyond it."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.clip(1.0 - i / i_near, 0.0, 1.0)


def crossings(s: FloatArray, mask: NDArray[np.bool_] | None = None, level: float = 0.5,
              probit: bool = True) -> FloatArray:
    """Fractional (row, col) (n, 2) where `s` (h, w) crosses `level` between 4-neighbours
    (both finite, both in `mask`), by interpolation along rows and columns.

    probit: interpolate the normal quantiles of s rather than s: a step blurred by a
    Gaussian footprint has s = Phi(x / sigma), whose quantile is linear in x, so the
    crossing does not lean toward the nearer pixel (linear interpolation of s does, by up
    to ~0.06 pixel with a footprint of half a pixel, depending on where the edge falls
    between pixel centres: a bias that a raster-aligned edge does not average out)."""
    s = np.asarray(s, dtype=float)
    if probit:
        from scipy.special import ndtri

        s = ndtri(np.clip(s, 0.02, 0.98))
        level = float(ndtri(level))
    ok = np.isfinite(s) if mask is None else (np.isfinite(s) & mask)
    out = []
    for axis in (1, 0):
        a = s[:, :-1] if axis == 1 else s[:-1, :]
        b = s[:, 1:] if axis == 1 else s[1:, :]
        oa = ok[:, :-1] if axis == 1 else ok[:-1, :]
        ob = ok[:, 1:] if axis == 1 else ok[1:, :]
        with np.errstate(invalid="ignore"):
            cross = oa & ob & ((a - level) * (b - level) < 0)
        ri, ci = np.nonzero(cross)
        t = (level - a[ri, ci]) / (b[ri, ci] - a[ri, ci])
        if axis == 1:
            out.append(np.column_stack([ri, ci + t]))
        else:
            out.append(np.column_stack([ri + t, ci]))
    return np.vstack(out) if out else np.zeros((0, 2))


def smooth_range(range_img: FloatArray, size: int = 5) -> FloatArray:
    """Mean of the valid ranges in a size x size window (nan stays nan): range noise down
    by about `size`, for normals."""
    from scipy import ndimage

    r = np.asarray(range_img, dtype=float)
    ok = np.isfinite(r)
    num = ndimage.uniform_filter(np.where(ok, r, 0.0), size)
    den = ndimage.uniform_filter(ok.astype(float), size)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    out[~ok] = np.nan
    return out
