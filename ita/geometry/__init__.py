"""The Geometric Reasoner and the Measurement Knowledge Base (MKB).

    from ita.geometry import build_mkb, GeometricReasoner, load_mkb, save_mkb
    mkb = build_mkb(cell, part, specs, tools, part_name="bulkhead", digest=mkb_digest(d, cell))
    save_mkb(mkb)                                  # ita_home()/mkb/bulkhead.json
    reasoner = GeometricReasoner(mkb, cell, specs)
    reasoner.resolve(in_contact_point(meas(Id)))   # Target(q, pose): the Executive's PoseResolver

Modules: :mod:`~ita.geometry.mkb` (the values and their file), :mod:`~ita.geometry.build`
(building the MKB from constraints and preferences), :mod:`~ita.geometry.reasoner`
(resolving plan terms), :mod:`~ita.geometry.configurations` (candidate tool poses and the
one configuration per measurement, shared with the Sequence Planner's cost).
"""

from ita.geometry.build import (
    GROUP_GROWTH,
    PRESS_M,
    build_mkb,
    mkb_digest,
    rack_configurations,
    view_groups,
)
from ita.geometry.mkb import (
    MKB_VERSION,
    MeasurementKB,
    MkbEntry,
    ViewGroup,
    load_mkb,
    mkb_path,
    save_mkb,
)
from ita.geometry.reasoner import GeometricReasoner, Target

__all__ = [
    "GROUP_GROWTH",
    "MKB_VERSION",
    "PRESS_M",
    "GeometricReasoner",
    "MeasurementKB",
    "MkbEntry",
    "Target",
    "ViewGroup",
    "build_mkb",
    "load_mkb",
    "mkb_digest",
    "mkb_path",
    "rack_configurations",
    "save_mkb",
    "view_groups",
]
