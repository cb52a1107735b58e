"""Which QIF characteristic carries each ITA measurement kind, and on which feature.

An explicit registry (:data:`CHARACTERISTICS`), read both ways: the results export
writes each kind as its QIF characteristic type, and the import takes a QIF
characteristic to the kinds it can be (:data:`KINDS_OF`), the geometry of its features
deciding among them.

    kind                               QIF characteristic   feature(s)
    web_thickness, flange_thickness    Thickness            Point (location, normal)
    hole_diameter                      Diameter             Circle, internal (the rim the SLRA sees)
    hole_position                      Position, diametrical zone, the DRF of the spec's datums
    edge_distance                      DistanceBetween      the hole's Circle and the edge's Plane
    flange_height, stiffener_height    Height               Plane (the top face)
    flange_width, stiffener_width      Width                OppositeParallelLines, external, on the top

Each characteristic item ITA writes carries its kind as the attribute ``ita.kind``: the
QIF type alone does not tell a flange from a stiffener, nor a web from a flange wall
whose thickness is measured from its cap.
"""

from __future__ import annotations

from ita.specs.model import MeasurementKind as K

#: the attribute on a characteristic item that names its ITA kind
KIND_ATTRIBUTE = "ita.kind"

#: kind -> the QIF characteristic type's stem (``<Stem>CharacteristicDefinition`` ...)
CHARACTERISTICS: dict[K, str] = {
    K.WEB_THICKNESS: "Thickness",
    K.FLANGE_THICKNESS: "Thickness",
    K.HOLE_DIAMETER: "Diameter",
    K.HOLE_POSITION: "Position",
    K.EDGE_DISTANCE: "DistanceBetween",
    K.FLANGE_HEIGHT: "Height",
    K.STIFFENER_HEIGHT: "Height",
    K.FLANGE_WIDTH: "Width",
    K.STIFFENER_WIDTH: "Width",
}

#: a result of no known kind: a user-defined linear characteristic naming what it is
UNKNOWN_KIND = "UserDefinedLinear"

#: QIF characteristic stem -> the ITA kinds it can be, the first the default when the
#: geometry does not decide (a height or a width: a stiffener's unless the file says flange)
KINDS_OF: dict[str, tuple[K, ...]] = {
    "Thickness": (K.WEB_THICKNESS, K.FLANGE_THICKNESS),
    "Diameter": (K.HOLE_DIAMETER,),
    "Position": (K.HOLE_POSITION,),
    "DistanceBetween": (K.EDGE_DISTANCE, K.WEB_THICKNESS, K.FLANGE_THICKNESS, K.STIFFENER_HEIGHT,
                        K.FLANGE_HEIGHT),
    "DistanceFrom": (K.EDGE_DISTANCE, K.WEB_THICKNESS, K.FLANGE_THICKNESS, K.STIFFENER_HEIGHT,
                     K.FLANGE_HEIGHT),
    "Height": (K.STIFFENER_HEIGHT, K.FLANGE_HEIGHT),
    "Width": (K.STIFFENER_WIDTH, K.FLANGE_WIDTH),
}

#: why ITA takes no characteristic of these QIF types, by family (the refusal's reason)
FAMILIES: dict[str, str] = {
    **{t: "a form tolerance" for t in ("Flatness", "Straightness", "Circularity", "Cylindricity", "Sphericity",
                                        "Conicity", "Ellipticity", "Toroidicity", "OtherForm")},
    **{t: "an orientation tolerance" for t in ("Perpendicularity", "Parallelism", "Angularity")},
    **{t: "a profile tolerance" for t in ("SurfaceProfile", "SurfaceProfileNonUniform", "LineProfile",
                                           "PointProfile")},
    **{t: "a runout tolerance" for t in ("CircularRunout", "TotalRunout")},
    **{t: "a location tolerance other than position" for t in ("Concentricity", "Coaxiality", "Symmetry")},
    **{t: "an angle" for t in ("Angle", "AngleBetween", "AngleFrom", "AngularCoordinate", "UserDefinedAngular")},
    **{t: "a radius" for t in ("Radius", "SphericalRadius")},
    "SphericalDiameter": "a sphere's diameter",
    "SurfaceTexture": "a surface texture",
    "Thread": "a thread",
}
