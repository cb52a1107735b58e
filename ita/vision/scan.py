"""Scan planning: the window and raster Vision asks of the SLRA for a spec, and how many
frames (each after its own approach of the arm) a spec needs.

    geometry = scan_for(spec, ctx)     # the window and pixels of the frame
    plan = frames_for(spec, ctx)       # frames to take (a pose-datum position averages several)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ita.part.model import FlangeSegment, Hole, HoleRole, Stiffener
from ita.sensors.slra_frame import ScanGeometry
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.vision.context import BLUR_MM, VisionContext, fastener_neighbours

FloatArray = NDArray[np.float64]


REAPPROACH_SHAPE = (128, 128)  # pixels of each re-approach frame (a rim fit needs no more)


MIN_HOLE_PIXELS = 11     # a fastener hole's position frame spans the hole's diameter with at least this many pixels


MIN_TOP_PIXELS = 4       # a rib height's frame puts at least this many pixels across the rib's top window


RASTER_STEP = 128        # a finer raster than ctx.shape grows in steps of this many pixels a side


MAX_RASTER = 1024        # and to at most this many


def _window_mm(spec: MeasurementSpec, ctx: VisionContext) -> float:
    f = ctx.features.get(spec.feature)
    margin = 2 * (BLUR_MM + 3.0) + 2.0
    if spec.kind is K.HOLE_DIAMETER and isinstance(f, Hole):
        return f.diameter + margin
    if spec.kind is K.HOLE_POSITION and isinstance(f, Hole):
        if f.role is HoleRole.FASTENER:
            nb = fastener_neighbours(f, ctx, 1e9)[:2]
            reach = max((math.dist(h.center[:2], f.center[:2]) + h.diameter / 2 for h in nb), default=f.diameter)
            return 2 * (reach + BLUR_MM + 9.0)
        return f.diameter + margin
    if spec.kind is K.EDGE_DISTANCE and isinstance(f, Hole):
        return 2 * (abs(spec.nominal) + 12.0)
    if spec.kind in (K.FLANGE_HEIGHT, K.FLANGE_WIDTH) and isinstance(f, FlangeSegment):
        # the patches reach 5 mm past the wall's face and 14 mm past the cap's free edge
        # (the web, ita.vision.kinds._flange), from the spec's point anywhere on the cap
        at = f.from_wall(spec.point)
        reach = max(at + BLUR_MM + 5.0, f.cap_width - at + BLUR_MM + 14.0)
        return 2 * (max(f.cap_width, reach) + 2.0)
    if spec.kind in (K.STIFFENER_HEIGHT, K.STIFFENER_WIDTH) and isinstance(f, Stiffener):
        # the webs beside the rib reach 14 mm across it and 10 along: at any roll of the
        # sensor about its axis the square window must hold that rectangle's corners
        return 2 * math.hypot(f.width / 2 + 14.0, 11.0)
    return 100.0


def scan_for(spec: MeasurementSpec, ctx: VisionContext) -> ScanGeometry:
    """The scan window and raster Vision asks of the SLRA for `spec` (from the nominal
    standoff): ctx.shape pixels, or more where :func:`_raster_for` needs them."""
    ang = math.degrees(2 * math.atan(_window_mm(spec, ctx) / 2 / (ctx.standoff_m * 1000)))
    fov = (min(ang, ctx.max_fov_deg[0]), min(ang, ctx.max_fov_deg[1]))
    return ScanGeometry(_raster_for(spec, ctx, fov), fov)


def _raster_for(spec: MeasurementSpec, ctx: VisionContext, fov_deg: tuple[float, float]) -> tuple[int, int]:
    """Pixels (rows, cols) of `spec`'s frame over a window of `fov_deg` (horizontal, vertical).

    A fastener hole's position is fitted on its own rim and its neighbours' half-rims, whose
    edge points grow with the pixels across a hole: where the window (wide enough for two
    neighbours) would put fewer than :data:`MIN_HOLE_PIXELS` across the hole's diameter at
    the nominal standoff, that axis gets the first multiple of :data:`RASTER_STEP` that puts
    that many (at most :data:`MAX_RASTER`).  Everything else: ctx.shape.
    """
    f = ctx.features.get(spec.feature)
    if spec.kind is K.STIFFENER_HEIGHT and isinstance(f, Stiffener):
        return _rib_top_raster(f, ctx, fov_deg)
    if not (spec.kind is K.HOLE_POSITION and isinstance(f, Hole) and f.role is HoleRole.FASTENER):
        return ctx.shape
    out = []
    for n, deg in zip(ctx.shape, (fov_deg[1], fov_deg[0])):     # rows span the vertical window
        window_mm = 2 * ctx.standoff_m * 1000 * math.tan(math.radians(deg) / 2)
        need = MIN_HOLE_PIXELS * window_mm / f.diameter
        out.append(n if need <= n else max(n, min(MAX_RASTER, RASTER_STEP * math.ceil(need / RASTER_STEP))))
    return out[0], out[1]


def _rib_top_raster(rib: Stiffener, ctx: VisionContext, fov_deg: tuple[float, float]) -> tuple[int, int]:
    """A rib height's raster: its top is read in a window that keeps the beam's blur and a
    pixel from both edges (ita.vision.kinds._stiffener), on a narrow rib a sliver of the
    default raster's pixels; the first multiple of :data:`RASTER_STEP` (at most
    :data:`MAX_RASTER`) that puts :data:`MIN_TOP_PIXELS` across it.  A rib whose top no
    raster clears of the blur keeps ctx.shape (the measurer says it cannot be measured)."""
    window_mm = 2 * ctx.standoff_m * 1000 * math.tan(math.radians(max(fov_deg)) / 2)
    n = max(ctx.shape)
    while n <= MAX_RASTER:
        pixel = window_mm / n
        if 2 * (rib.width / 2 - BLUR_MM - pixel) >= MIN_TOP_PIXELS * pixel:
            return (n, n) if n > max(ctx.shape) else ctx.shape
        n = RASTER_STEP * (n // RASTER_STEP + 1)
    return ctx.shape


@dataclass(frozen=True)
class FramePlan:
    """The frames a spec needs: `count` frames, each after its own approach of the arm (a
    new draw of its pose error), the first of the spec's window, the others of `shape`
    pixels over the same window."""

    count: int
    shape: tuple[int, int]


def frames_for(spec: MeasurementSpec, ctx: VisionContext) -> FramePlan:
    """How many frames `spec` needs.  A lightening hole's position has no datum in view but
    the arm's pose, whose error (repeatability) is new at every approach: the deviations of
    up to ctx.pose_datum_frames approaches are averaged (the SLRA stops as soon as they
    decide it, ita.devices.slra) (:func:`ita.vision.measure.measure_frames`), at
    :data:`REAPPROACH_SHAPE` pixels (its rim has hundreds of edge points even so).
    Everything else needs one frame."""
    f = ctx.features.get(spec.feature)
    if spec.kind is K.HOLE_POSITION and isinstance(f, Hole) and f.role is not HoleRole.FASTENER:
        return FramePlan(max(1, ctx.pose_datum_frames), REAPPROACH_SHAPE)
    return FramePlan(1, ctx.shape)
