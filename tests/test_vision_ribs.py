"""A flange height's web patch keeps clear of a rib that meets the flange beside its point
(on a generated part, which Vision knows by its features, not by a mesh): the pixels whose
ray meets the rib, or its side, on the way down to the web are left out."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ita.part.model import Stiffener
from ita.sensors.slra_frame import RangeFrame, ScanGeometry
from ita.vision.kinds import _clear_of_ribs
from ita.vision.patches import View
from ita.vision.rims import rect_patch


def _looking_down_at(placement, xy, standoff_mm: float = 450.0, shape=(96, 96)) -> View:
    """A frame whose reported pose looks straight down at part point xy from standoff_mm."""
    r_part = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])     # columns: sensor axes
    pose = np.eye(4)
    pose[:3, :3] = placement.rotation_matrix() @ r_part
    pose[:3, 3] = placement.to_world(np.array([[xy[0], xy[1], standoff_mm]]))[0]
    geometry = ScanGeometry(shape, (20.0, 20.0))
    frame = RangeFrame(np.full(shape, np.nan), np.zeros(shape), pose, geometry)
    return View(frame, placement)


def test_pixels_whose_rays_meet_a_rib_are_left_out_of_the_web(builtin_part) -> None:
    from ita.vision.for_part import vision_context
    from ita.workcell import load_workcell

    cell = load_workcell()
    ctx = vision_context(builtin_part, cell)
    web_z = 2.5
    rib = Stiffener("R-TEST", (0.0, -100.0), (0.0, 100.0), 3.5, 28.0)     # along y through x = 0
    view = _looking_down_at(cell.part, (20.0, 0.0))
    patch, _ = rect_patch(view, "web", np.array([-8.0, 0.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]),
                          (0.0, 16.0), (-8.0, 8.0), web_z)
    without = _clear_of_ribs(view, patch, web_z, replace(ctx, features={}))
    assert without.all()                                              # no rib: every pixel is clear
    clear = _clear_of_ribs(view, patch, web_z, replace(ctx, features={rib.id: rib}))
    x = np.asarray(view.origin[:2])                                   # the sensor stands at x = 20
    from ita.vision.patches import nominal_points

    xy = nominal_points(view, patch, web_z)[..., :2]
    on_rib = np.abs(xy[..., 0]) < rib.width / 2                       # the rib's own footprint
    assert not clear[on_rib].any()
    far = xy[..., 0] > rib.width / 2 + 3.0                            # between the rib and the sensor: seen
    assert clear[far].all()
    # beyond the rib, seen from x = 20, the rays pass over the rib's top: those near it are hidden
    behind = (xy[..., 0] < -rib.width / 2) & (xy[..., 0] > -rib.width / 2 - (rib.height - web_z) * 20.0 / 450.0)
    assert x[0] > 0 and behind.any() and not clear[behind].any()


def test_vision_that_finds_nothing_to_measure_on_raises_no_cable_fault() -> None:
    """VISION(not_measurable) (the nominal part leaves nothing in the view to measure the
    feature on) is the exception view_not_measurable, not an implausible range image (whose
    likely cause is a sensor cable)."""
    from ita.diagnosis.classify import classify_reply
    from ita.logic.terms import Term

    assert classify_reply("exception", Term("VISION", ("not_measurable",))) == "view_not_measurable"
    assert classify_reply("exception", Term("VISION", ("garbage",))) == "range_image_implausible"


def test_a_narrow_ribs_top_is_found_where_the_frame_shows_it() -> None:
    """An arm's lateral error of a few tenths moves a 2.5 mm rib's top window onto its
    edges; the window is centred on the plateau the frame shows (the median across of the
    pixels at the top's height), not where the reported pose puts it."""
    from ita.vision.kinds import _rib_offset

    t = np.tile(np.linspace(-6.0, 6.0, 121), (40, 1))              # mm across the rib, 0.1 mm pixels
    shift = 0.3                                                     # the rib lies 0.3 mm off nominal
    z = np.where(np.abs(t - shift) < 1.25, 36.0, 3.0)
    z = z + np.random.default_rng(1).normal(0.0, 0.02, z.shape)
    z[:, ::17] = np.nan                                             # dropouts
    region = np.ones(z.shape, dtype=bool)
    assert abs(_rib_offset(z, t, region, 36.0, 2.4) - shift) < 0.06
    assert _rib_offset(np.full(z.shape, 3.0), t, region, 36.0, 2.4) == 0.0    # no plateau seen: nominal


def test_a_narrow_ribs_height_frame_has_pixels_across_its_top(builtin_part) -> None:
    """The window that keeps the beam's blur from a rib's edges is a sliver of the default
    raster on a narrow rib: its height's frame gets the raster that puts MIN_TOP_PIXELS
    across it; a wide rib keeps the default, and one whose top no raster clears keeps it too
    (the measurer says it cannot be measured)."""
    from ita.part.model import Stiffener
    from ita.specs.model import MeasurementKind as K
    from ita.specs.model import MeasurementSpec
    from ita.vision.context import BLUR_MM
    from ita.vision.for_part import vision_context
    from ita.vision.scan import MIN_TOP_PIXELS, scan_for
    from ita.workcell import load_workcell

    ctx = vision_context(builtin_part, load_workcell())

    def frame_for(width: float):
        rib = Stiffener("R-TEST", (0.0, -100.0), (0.0, 100.0), width, 36.0)
        spec = MeasurementSpec("SH-TEST", K.STIFFENER_HEIGHT, rib.id, (0.0, 0.0, 36.0), (0.0, 0.0, 1.0), 36.0,
                               -0.25, 0.25)
        return scan_for(spec, replace(ctx, features={**ctx.features, rib.id: rib}))

    def pixels_across_top(width: float, g) -> float:
        window = 2 * ctx.standoff_m * 1000 * np.tan(np.radians(max(g.fov_deg)) / 2)
        pixel = window / max(g.shape)
        return 2 * (width / 2 - BLUR_MM - pixel) / pixel

    narrow, wide, too_narrow = frame_for(2.5), frame_for(6.0), frame_for(1.8)
    assert max(narrow.shape) > max(ctx.shape) and pixels_across_top(2.5, narrow) >= MIN_TOP_PIXELS
    assert wide.shape == ctx.shape and pixels_across_top(6.0, wide) >= MIN_TOP_PIXELS
    assert too_narrow.shape == ctx.shape
