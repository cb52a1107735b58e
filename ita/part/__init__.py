"""The part to inspect: a parametric bulkhead generator, part loading and pictures.

Public entry points: `load_part(dir | None)` (ita.part.store), `generate(params)`
(ita.part.bulkhead), `summarize(part)` (ita.part.summary), `render_part(part, path)`
(ita.part.render).  The as-built truth lives in ita.part.truth, which only the simulator
and the scoring may import; this package does not import it.
"""

from ita.part.model import (
    Feature,
    FeatureKind,
    FlangeSegment,
    Hole,
    HoleRole,
    Part,
    Pocket,
    Stiffener,
)

__all__ = [
    "Feature", "FeatureKind", "FlangeSegment", "Hole", "HoleRole", "Part", "Pocket", "Stiffener",
]
