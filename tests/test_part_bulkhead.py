"""The generated bulkhead: a watertight part of the right size with ~1000 sound specs."""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from ita.part.bulkhead import generate, load_params
from ita.part.mesh import build_mesh
from ita.part.model import (
    FeatureKind,
    Hole,
    HoleRole,
    feature_from_dict,
    feature_to_dict,
)
from ita.specs.model import MeasurementKind as K

HOLE_KINDS = {K.HOLE_DIAMETER, K.HOLE_POSITION}


def test_mesh_is_watertight_and_bulkhead_sized(bulkhead):
    mesh = bulkhead.mesh
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    lo, hi = mesh.bounds
    assert np.allclose(hi - lo, [2500.0, 1500.0, 45.0], atol=0.5)
    assert lo[2] == pytest.approx(0.0)  # datum A, the web's back face


def test_mesh_survives_stl_round_trip(bulkhead, tmp_path):
    bulkhead.mesh.export(tmp_path / "p.stl")
    assert trimesh.load(tmp_path / "p.stl").is_watertight


def test_about_a_thousand_specs_of_every_kind(bulkhead):
    specs = bulkhead.specs
    counts = Counter(s.kind for s in specs)
    assert 900 <= len(specs) <= 1200
    assert set(counts) == set(K)
    assert counts[K.WEB_THICKNESS] == 200
    assert len({s.id for s in specs}) == len(specs)


def test_every_spec_names_a_feature_and_datum(bulkhead):
    ids = {f.id for f in bulkhead.features}
    for s in bulkhead.specs:
        assert s.feature in ids, s.id
        assert s.datum in ("A", "A|B|C")
        assert s.lower < s.upper
    kinds = Counter(f.kind for f in bulkhead.features)
    assert set(kinds) == set(FeatureKind)
    datums = {h.datum for h in bulkhead.features if isinstance(h, Hole) and h.datum}
    assert datums == {"B", "C"}


def test_tolerances_are_realistic(bulkhead):
    for s in bulkhead.specs:
        if s.kind in (K.WEB_THICKNESS, K.FLANGE_THICKNESS):
            assert (s.lower, s.upper) == (-0.127, 0.127)
        if s.kind is K.HOLE_POSITION:
            assert s.nominal == 0 and s.lower == 0 and s.upper in (0.5, 1.0)


def test_spec_points_lie_on_the_surface_with_its_normal(bulkhead):
    specs = [s for s in bulkhead.specs if s.kind not in HOLE_KINDS]
    pts = np.array([s.point for s in specs])
    _, dist, tri = trimesh.proximity.closest_point(bulkhead.mesh, pts)
    assert dist.max() < 0.05
    dots = np.einsum("ij,ij->i", bulkhead.mesh.face_normals[tri], np.array([s.normal for s in specs]))
    assert dots.min() > 0.99
    assert all(s.normal[2] >= 0 for s in bulkhead.specs)  # all seen or touched from +Z


def test_hole_points_are_centres_on_the_entry_face(bulkhead):
    holes = {f.id: f for f in bulkhead.features if isinstance(f, Hole)}
    specs = [s for s in bulkhead.specs if s.kind in HOLE_KINDS]
    pts = np.array([s.point for s in specs])
    _, dist, _ = trimesh.proximity.closest_point(bulkhead.mesh, pts)
    radius = np.array([holes[s.feature].diameter / 2 for s in specs])
    assert np.allclose(dist, radius, atol=0.05)
    sizes = Counter(round(h.diameter, 2) for h in holes.values() if h.role is HoleRole.FASTENER)
    assert set(sizes) <= {6.35, 5.0}
    lh = [h.diameter for h in holes.values() if h.role is HoleRole.LIGHTENING]
    assert len(lh) >= 10 and min(lh) >= 60 and max(lh) <= 200


def test_widths_and_edge_distances_have_an_in_plane_direction(bulkhead):
    for s in bulkhead.specs:
        if s.kind in (K.FLANGE_WIDTH, K.STIFFENER_WIDTH, K.EDGE_DISTANCE):
            assert s.direction is not None and abs(s.direction[2]) < 1e-9
            assert np.linalg.norm(s.direction) == pytest.approx(1.0)
        else:
            assert s.direction is None


def test_generation_is_deterministic_and_seeded(bulkhead):
    params = load_params()
    again = generate(params)
    assert again.specs == bulkhead.specs
    assert again.features == bulkhead.features
    other = generate(replace(params, part=replace(params.part, seed=7)))
    assert [s.point for s in other.specs] != [s.point for s in bulkhead.specs]


def test_features_round_trip_through_dicts(bulkhead):
    for f in bulkhead.features:
        assert feature_from_dict(feature_to_dict(f)) == f


def test_mesh_is_rebuilt_from_features_alone(bulkhead):
    rebuilt = build_mesh(bulkhead.features)
    assert rebuilt.volume == pytest.approx(bulkhead.mesh.volume, rel=1e-9)


def test_generation_is_fast():
    start = time.process_time()
    generate(load_params())
    assert time.process_time() - start < 20.0  # about 1 s here; generous for shared CI
