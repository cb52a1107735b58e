"""What Vision knows besides a frame, and what it answers: the context (nominal features,
the part's placement, the SLRA's window and the tolerances a reference needs), the
replies (a value with its standard uncertainty, or an exception reply with the reason),
and the constants of its method (see :mod:`ita.vision.measure`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING, Any, Union

import numpy as np
from numpy.typing import NDArray

from ita.part import geometry2d as g2
from ita.part.infer import MeshRays
from ita.part.model import Feature, Hole, HoleRole, Pocket
from ita.specs.model import MeasurementKind as K
from ita.vision.patches import Views
from ita.workcell.model import PartPlacement

if TYPE_CHECKING:
    from ita.vision.calibration import SlraCalibration

FloatArray = NDArray[np.float64]


SLRA_KINDS = (K.HOLE_DIAMETER, K.HOLE_POSITION, K.FLANGE_HEIGHT, K.FLANGE_WIDTH,
              K.STIFFENER_HEIGHT, K.STIFFENER_WIDTH, K.EDGE_DISTANCE)


BLUR_MM = 1.0            # edge band half-width: >= 3 sigma of the SLRA's beam footprint


SURFACE_BAND_MM = 3.0    # a face's pixels lie within this of its nominal height


STEP_CLEAR_MM = 1.5      # on a part known by its mesh, a flange height's faces use only pixels this far (at
                         # the face, in the image) from another nominal surface: 4.5 sigma of the beam's
                         # footprint (BLUR_MM is 3), beyond which a 40 mm step moves a range by < 0.2 um
FACE_MATCH_MM = 0.01     # a nominal ray meets such a face when its hit lies this close to the face's height


OCCLUDER_MM = 3.0        # a pixel this far in front of a face occludes it


MAX_OCCLUDED = 0.25      # share of a patch's pixels in front that makes it occluded


MIN_PLANE_PIXELS = 25


MIN_EDGE_POINTS = 12


MAX_PLANE_RMS_MM = 0.6


MAX_EDGE_RMS_MM = 0.3    # plus half a pixel


EDGE_CORRELATION = 1.6   # inflates edge-fit sigmas: row and column crossings share pixels


EDGE_MODEL_PX = 0.05     # residual bias of a sub-pixel edge point (pixels), not averaged away


RIM_EDGE_MODEL_PX = 0.01  # the same bias on a radius fitted over a whole rim: its points sample every sub-pixel
                          # phase and direction, so what is left is the model's mean bias (bench/vision.py)


WHOLE_RIM = 0.9 * 2 * math.pi  # a rim whose points span this much (rad) is whole


MIX_RANGE_MM = 100.0     # a surface this far beyond the face mixes with it in phase (range share)


FAR_SPREAD_MM = 2.0      # beyond a rim, heights this far from their median are another surface,


FAR_MIXED_SHARE = 0.03   # and more than this share of them means several surfaces


FAR_MIXED_U_MM = 0.06    # then the rim's position (radius, centre) carries this much more


FAR_CHECK_MM = 0.6       # the surface just beyond a rim is looked for this far inside it (2 sigma of the beam)


DATUM_MIN_COVERAGE = math.radians(120)  # rim span a datum neighbour's fit needs


DIAMETER_TOLERANCE = 0.076  # +/- of a hole's diameter when its spec does not say


MAX_DATUM_HOLES = 6      # a fastener hole registers on at most this many neighbours in view


POSE_DATUM_FRAMES = 16   # re-approaches averaged for a position whose only datum is the pose


class VisionFailure(str, Enum):
    """Why a measurement could not be made."""

    OUT_OF_VIEW = "out_of_view"
    OCCLUDED = "occluded"
    TOO_FEW_PIXELS = "too_few_pixels"
    FIT_RESIDUAL = "fit_residual"
    NOT_MEASURABLE = "not_measurable"


@dataclass(frozen=True)
class VisionException:
    """The reply when a measurement cannot be made: the reason and what was seen."""

    spec_id: str
    reason: VisionFailure
    detail: str = ""
    ok = False


@dataclass(frozen=True)
class VisionResult:
    """A measured value (mm) with its standard uncertainty u (mm); U = 2u expanded."""

    spec_id: str
    kind: K
    value: float
    uncertainty: float
    diagnostics: dict[str, Any] = field(default_factory=dict, compare=False)
    ok = True

    @property
    def expanded(self) -> float:
        """Expanded uncertainty U = 2u (about 95 %)."""
        return 2.0 * self.uncertainty


VisionReply = Union[VisionResult, VisionException]  # noqa: UP007 (a runtime alias)


class VisionFail(Exception):
    def __init__(self, reason: VisionFailure, detail: str):
        super().__init__(detail)
        self.reason, self.detail = reason, detail


@dataclass(frozen=True)
class VisionContext:
    """What Vision knows besides the frame: nominal features, the part's placement, the
    SLRA's nominal standoff and largest window, and tolerances it needs for references.

    web_tolerance: +/- of the web thickness (a height's reference); position_zones: hole id
    -> true-position zone diameter; diameter_tolerances: hole id -> +/- of its diameter
    (a datum neighbour's radius, see :func:`register_on_neighbours`); pose_sigma_m: the
    arm's pose error per axis (1 sigma);
    pose_datum_frames: frames (each from its own approach) averaged for a position whose
    only datum is the pose (see :func:`frames_for`); calibration: the SLRA's calibration on
    reference workpieces (ita.vision.calibration.SlraCalibration; None: none, the
    measurers' type-B terms stand); floor: for a part without pockets among its features
    (one whose features were found on its mesh), the nominal mesh's height below a point
    (:class:`MeshFloor`), the web a height is measured from; views: the Views of the last
    few frames measured (ita.vision.patches.Views: a group's members share them).
    """

    features: Mapping[str, Feature]
    placement: PartPlacement
    standoff_m: float = 0.45
    max_fov_deg: tuple[float, float] = (30.0, 24.0)
    web_tolerance: float = 0.127
    position_zones: Mapping[str, float] = field(default_factory=dict)
    pose_sigma_m: float = 0.25e-3 / 3
    #: the part's registration on its datums: standard uncertainty (mm, per axis) of where
    #: it puts a point of the part, at its farthest corner (ita.task.align; 0: not registered)
    registration_u_mm: float = 0.0
    shape: tuple[int, int] = (256, 256)
    pose_datum_frames: int = POSE_DATUM_FRAMES
    diameter_tolerances: Mapping[str, float] = field(default_factory=dict)
    calibration: SlraCalibration | None = None
    floor: MeshFloor | None = None
    views: Views = field(default_factory=Views, compare=False, repr=False)

    def pockets(self) -> list[Pocket]:
        return [f for f in self.features.values() if isinstance(f, Pocket)]

    def web_at(self, xy: FloatArray) -> float | None:
        """Nominal web height (mm) of the pocket containing part point (2,), if any."""
        for p in self.pockets():
            if g2.points_in_polygon(np.atleast_2d(xy), p.outline_array)[0]:
                return p.web_thickness
        return None if self.floor is None else self.floor.height(xy)

    def web_region(self, xy: FloatArray) -> str | None:
        """The floor that part point (2,) lies on, named: its pocket ("pocket P07"), else
        the nominal mesh's flat facet met straight down ("facet 1234"); None: neither."""
        for p in self.pockets():
            if g2.points_in_polygon(np.atleast_2d(xy), p.outline_array)[0]:
                return f"pocket {p.id}"
        return None if self.floor is None else self.floor.region(xy)


class MeshFloor:
    """Heights of a nominal mesh's upward faces seen from above (mm, part frame)."""

    def __init__(self, mesh: Any):
        self.top = float(np.asarray(mesh.bounds)[1, 2]) + 10.0
        self.rays = MeshRays(mesh)

    def height(self, xy: FloatArray) -> float | None:
        """Height (mm) of the first face met straight down at part point (2,), if it faces up."""
        dist, face = self.rays.hits(np.array([[float(xy[0]), float(xy[1]), self.top]]), np.array([[0.0, 0.0, -1.0]]))
        if face[0] < 0 or self.rays.normals[face[0], 2] < 0.99:
            return None
        return self.top - float(dist[0])

    def region(self, xy: FloatArray) -> str | None:
        """The flat facet (coplanar faces joined by edges) of the upward face met straight
        down at part point (2,), named by its lowest face index; None: no upward face."""
        dist, face = self.rays.hits(np.array([[float(xy[0]), float(xy[1]), self.top]]), np.array([[0.0, 0.0, -1.0]]))
        if face[0] < 0 or self.rays.normals[face[0], 2] < 0.99:
            return None
        return f"facet {int(self._facet_of[face[0]])}"

    @functools.cached_property
    def _facet_of(self) -> NDArray[np.int64]:
        """Per face, the lowest face index of its facet (itself when in none)."""
        mesh = self.rays.mesh
        out = np.arange(len(mesh.faces), dtype=np.int64)
        for group in mesh.facets:
            out[group] = int(np.min(group))
        return out


def fastener_neighbours(hole: Hole, ctx: VisionContext, within: float) -> list[Hole]:
    """The fastener holes drilled into the same face as `hole` (same axis, entry within
    1 mm along it) within `within` mm across the axis, nearest first."""
    if hole.axis[2] > 0.999999:       # along +Z: the faces are heights, the distances in XY
        out = [h for h in ctx.features.values() if isinstance(h, Hole) and h.role is HoleRole.FASTENER
               and h.id != hole.id and h.axis[2] > 0.999999 and abs(h.center[2] - hole.center[2]) < 1.0
               and math.dist(h.center[:2], hole.center[:2]) < within]
        return sorted(out, key=lambda h: math.dist(h.center[:2], hole.center[:2]))
    axis = np.asarray(hole.axis, dtype=float)
    c = np.asarray(hole.center, dtype=float)

    def across(h: Hole) -> float:
        d = np.asarray(h.center) - c
        return float(np.linalg.norm(d - np.dot(d, axis) * axis))

    out = [h for h in ctx.features.values() if isinstance(h, Hole) and h.role is HoleRole.FASTENER
           and h.id != hole.id and float(np.dot(h.axis, axis)) > 0.999
           and abs(float(np.dot(np.asarray(h.center) - c, axis))) < 1.0 and across(h) < within]
    return sorted(out, key=across)
