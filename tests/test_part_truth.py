"""The as-built truth: its statistics, and the boundary that keeps it from the planners."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from ita.part import truth as truth_mod
from ita.part.mesh_values import mesh_values
from ita.part.model import Pocket
from ita.specs.model import MeasurementKind as K

REPO = Path(__file__).resolve().parents[1]
# modules that may know the truth: its own module, the store that writes it, the serials'
# as-built parts (which make a serial's truth as the store makes the part's), the simulator and
# the scoring
ALLOWED = ("ita/part/truth.py", "ita/part/store.py", "ita/part/serials.py", "ita/sim/", "ita/scoring/")
TRUTH_NAMES = {truth_mod.TRUTH_DIR, truth_mod.MESH_FILE, truth_mod.FEATURES_FILE, truth_mod.VALUES_FILE}


@pytest.fixture(scope="module")
def truth(bulkhead):
    return truth_mod.make_truth(bulkhead)


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the docstring nodes (prose may name the truth; code may not)."""
    ids = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                ids.add(id(body[0].value))
    return ids


def _violations(source: str) -> list[str]:
    found = []
    tree = ast.parse(source)
    prose = _docstrings(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.startswith("ita.part.truth")]
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if mod.startswith("ita.part.truth") or (mod == "ita.part" and any(a.name == "truth" for a in node.names)):
                found.append(f"from {mod} import ...")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in prose:
            text = node.value
            parts = set(text.replace("\\", "/").split("/"))
            if "ita.part.truth" in text or parts & TRUTH_NAMES:
                found.append(repr(text))
    return found


def test_boundary_scan_catches_what_it_should():
    assert _violations("from ita.part import truth")
    assert _violations("import ita.part.truth as t")
    assert _violations("p = part_dir / 'truth' / 'x'")
    assert _violations("open('parts/bulkhead/truth/asbuilt.ply')")
    assert _violations("importlib.import_module('ita.part.truth')")
    assert not _violations("'ground truth is known to the simulator only'")
    assert not _violations('"""Docs may say: ita.part.truth is for the simulator."""')


def test_only_simulator_and_scoring_touch_the_truth():
    offenders = {}
    for path in sorted((REPO / "ita").rglob("*.py")):
        rel = path.relative_to(REPO).as_posix()
        if rel.startswith(ALLOWED):
            continue
        bad = _violations(path.read_text(encoding="utf-8"))
        if bad:
            offenders[rel] = bad
    assert not offenders, f"modules reaching into the as-built truth: {offenders}"


def test_every_feature_deviates(bulkhead, truth):
    nominal = {f.id: f for f in bulkhead.features}
    changed = [f.id for f in truth.features if f != nominal[f.id]]
    tooling = [f.id for f in bulkhead.features if getattr(f, "datum", "")]
    assert len(changed) == len(bulkhead.features)  # tooling holes still vary in diameter
    assert tooling


def test_deviation_spread_is_a_quarter_of_the_tolerance(bulkhead, truth):
    out = set(truth.out_of_tolerance)
    devs = np.array([truth.deviations[f.id]["web_thickness"] for f in bulkhead.features
                     if isinstance(f, Pocket) and f.id not in out])
    flange = np.array([d["cap_thickness"] for fid, d in truth.deviations.items()
                       if "cap_thickness" in d and fid not in out])
    both = np.concatenate([devs, flange]) / 0.127
    assert 0.15 < both.std() < 0.35
    assert abs(both.mean()) < 0.15


def test_about_two_percent_of_features_out_of_tolerance(bulkhead, truth):
    n = len(bulkhead.features)
    assert len(truth.out_of_tolerance) == round(0.02 * n)
    specs_out = {s.feature for s in bulkhead.specs
                 if s.id in truth.values and not s.low_limit <= truth.values[s.id] <= s.high_limit}
    assert specs_out  # some measured values really are out of tolerance
    assert specs_out <= set(truth.out_of_tolerance) | {h.id for h in truth.features if h.kind.value == "hole"}
    assert len(specs_out) <= 3 * len(truth.out_of_tolerance)


def test_true_values_follow_the_features(bulkhead, truth):
    act = {f.id: f for f in truth.features}
    nom = {f.id: f for f in bulkhead.features}
    for s in bulkhead.specs:
        v = truth.values[s.id]
        if s.kind is K.WEB_THICKNESS:
            assert v == pytest.approx(act[s.feature].web_thickness, abs=1e-6)
        elif s.kind is K.HOLE_POSITION:
            assert v == pytest.approx(2 * math.dist(act[s.feature].center[:2], nom[s.feature].center[:2]), abs=1e-6)
        elif s.kind is K.STIFFENER_WIDTH:
            assert v == pytest.approx(act[s.feature].width, abs=1e-6)


def test_asbuilt_mesh_is_watertight_and_differs(bulkhead, truth):
    assert truth.mesh.is_watertight
    assert truth.mesh.volume != pytest.approx(bulkhead.mesh.volume, rel=1e-7)
    assert truth.mesh.volume == pytest.approx(bulkhead.mesh.volume, rel=1e-2)


def test_asbuilt_web_thickness_is_in_the_mesh(bulkhead, truth):
    spec = next(s for s in bulkhead.specs if s.kind is K.WEB_THICKNESS)
    origin = np.array([[spec.point[0], spec.point[1], 10.0]])
    hits, _, _ = truth.mesh.ray.intersects_location(origin, np.array([[0.0, 0.0, -1.0]]))
    assert hits[:, 2].max() == pytest.approx(truth.values[spec.id], abs=1e-4)


def test_truth_is_deterministic(bulkhead, truth):
    again = truth_mod.make_truth(bulkhead)
    assert again.values == truth.values and again.out_of_tolerance == truth.out_of_tolerance


def test_truth_round_trips_and_is_stored_apart(builtin_part, bulkhead):
    loaded = truth_mod.load_truth(builtin_part.directory)
    assert (builtin_part.directory / "truth").is_dir()
    assert loaded.mesh.is_watertight
    assert set(loaded.values) == {s.id for s in bulkhead.specs}
    fresh = truth_mod.make_truth(bulkhead)
    assert loaded.values == fresh.values


def test_user_part_without_truth_says_so(tmp_path):
    from ita.errors import InputError

    with pytest.raises(InputError, match="no as-built truth"):
        truth_mod.load_truth(tmp_path)


def test_a_mesh_s_own_values_agree_with_the_generated_truth(builtin_part):
    """The values exact rays find on the as-built mesh are the generator's true values: what
    scores a part simulated from a mesh.  Hole diameters read the mesh's polygons (chord sag
    0.02 mm), a little small; edge distances on corner arcs read along the spec's direction."""
    from collections import defaultdict

    from ita.specs.io import read_specs

    t = truth_mod.load_truth(builtin_part.directory)
    specs = read_specs(builtin_part.specs_path)
    got = mesh_values(t.mesh, specs, {f.id: f for f in builtin_part.features})
    assert set(got) == {s.id for s in specs}
    err = defaultdict(list)
    for s in specs:
        err[s.kind.value].append(got[s.id] - t.values[s.id])
    for kind in ("web_thickness", "flange_thickness", "flange_height", "stiffener_height", "stiffener_width",
                 "hole_position"):
        assert max(map(abs, err[kind])) < 1e-3, kind
    assert max(map(abs, err["flange_width"])) < 5e-3
    assert -0.03 < min(err["hole_diameter"]) and max(err["hole_diameter"]) < -0.015
    assert abs(float(np.mean(err["edge_distance"]))) < 0.005
