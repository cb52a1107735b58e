"""Spec-file operations on a part: validated against the mesh, all or nothing, atomic."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ita.errors import InputError
from ita.part import specfile
from ita.specs.io import COLUMNS, read_specs

HEADER = ",".join(COLUMNS)
# A 100 x 50 x 2.5 mm plate with its back face at z = 0, a 6 mm hole through it at (80, 10).
PLATE = trimesh.creation.box(extents=(100.0, 50.0, 2.5),
                             transform=trimesh.transformations.translation_matrix((50, 25, 1.25))).difference(
    trimesh.creation.cylinder(radius=3.0, height=10.0, sections=96,
                              transform=trimesh.transformations.translation_matrix((80, 10, 0))))
ROWS = [
    "WT-1,web_thickness,P01,10,20,2.5,0,0,1,2.5,-0.127,0.127,A,,,,",
    "WT-2,web_thickness,P01,60,30,2.5,0,0,1,2.5,-0.127,0.127,A,,,,",
    "HD-1,hole_diameter,H1,80,10,2.5,0,0,1,6.0,-0.05,0.05,A,,,,",
]


@dataclass(frozen=True)
class Plate:
    specs_path: Path
    mesh: trimesh.Trimesh = PLATE


@pytest.fixture
def part(tmp_path: Path) -> Plate:
    path = tmp_path / "specs.csv"
    path.write_text("\n".join([HEADER, *ROWS]) + "\n")
    return Plate(path)


def test_validate_accepts_points_on_the_surface(part: Plate) -> None:
    assert specfile.validate_file(part) == (3, [])


def test_point_off_the_surface_is_rejected_with_its_line(part: Plate, tmp_path: Path) -> None:
    other = tmp_path / "other.csv"
    other.write_text("\n".join([HEADER, ROWS[0], ROWS[1].replace(",2.5,0,0,1", ",9.5,0,0,1", 1)]))
    with pytest.raises(InputError) as info:
        specfile.validate_file(part, other)
    (loc, msg), = info.value.problems
    assert (loc.file, loc.line) == (str(other), 3)
    assert "WT-2 is 7.000 mm from the part's surface" in msg


def test_hole_centre_may_lie_within_the_hole_radius(part: Plate) -> None:
    # the centre on the entry face is the hole's radius (3 mm) from the nearest surface
    specfile.add(part, {"id": "HP-1", "kind": "hole_position", "feature": "H1", "x": "80",
                       "y": "10", "z": "2.5", "nx": "0", "ny": "0", "nz": "1", "nominal": "0",
                       "lower": "0", "upper": "0.5", "datum": "A|B|C"})
    with pytest.raises(InputError, match="from the part's surface"):
        specfile.add(part, {"id": "HP-2", "kind": "hole_position", "feature": "H1", "x": "80",
                           "y": "10", "z": "9.0", "nx": "0", "ny": "0", "nz": "1", "nominal": "0",
                           "lower": "0", "upper": "0.5", "datum": "A|B|C"})


def test_a_hole_spec_where_the_mesh_has_no_hole_is_a_warning_naming_it(part: Plate, tmp_path: Path) -> None:
    other = tmp_path / "other.csv"
    other.write_text("\n".join([HEADER, *ROWS, "HD-2,hole_diameter,H2,30,30,2.5,0,0,1,6.0,-0.05,0.05,A,,,,",
                                "HD-3,hole_diameter,H3,80,10,2.5,0,0,1,8.0,-0.05,0.05,A,,,,"]) + "\n")
    n, warnings = specfile.validate_file(part, other)      # warnings: a run marks them cannot be done
    (loc2, msg2), (loc3, msg3) = warnings
    assert n == 5
    assert (loc2.line, loc2.field, loc3.line) == (5, "feature", 6)
    assert "HD-2: feature 'H2' not found" in msg2 and "no hole at (30.0, 30.0, 2.5)" in msg2
    assert re.search(r"is 6\.00\d mm across; its diameter spec says 8\.000 mm", msg3)


def test_add_edit_remove(part: Plate) -> None:
    specfile.add(part, {"id": "WT-3", "kind": "web_thickness", "feature": "P02", "x": "5",
                       "y": "5", "z": "2.5", "nx": "0", "ny": "0", "nz": "1", "nominal": "2.5",
                       "lower": "-0.127", "upper": "0.127", "datum": "A"})
    specfile.change(part, "WT-3", {"nominal": "2.6", "id": "WT-33"})
    specs = {s.id: s for s in read_specs(part.specs_path)}
    assert specs["WT-33"].nominal == 2.6 and "WT-3" not in specs
    assert specfile.remove(part, ["WT-33", "WT-1"]) == 2


@pytest.mark.parametrize(
    "operation",
    [
        lambda p: specfile.add(p, {"id": "WT-1", "kind": "web_thickness", "feature": "P",
                                  "x": "1", "y": "1", "z": "2.5", "nx": "0", "ny": "0", "nz": "1",
                                  "nominal": "2.5", "lower": "-0.1", "upper": "0.1", "datum": "A"}),
        lambda p: specfile.change(p, "WT-1", {"lower": "0.3"}),
        lambda p: specfile.change(p, "WT-1", {"z": "40"}),
        lambda p: specfile.change(p, "WT-1", {"id": "WT-2"}),
        lambda p: specfile.change(p, "NOPE", {"nominal": "1"}),
        lambda p: specfile.remove(p, ["WT-1", "NOPE"]),
    ],
)
def test_rejected_changes_write_nothing(part: Plate, operation) -> None:
    before = part.specs_path.read_bytes()
    with pytest.raises(InputError):
        operation(part)
    assert part.specs_path.read_bytes() == before


def test_import_merges_and_refuses_existing_ids(part: Plate, tmp_path: Path) -> None:
    new = tmp_path / "new.csv"
    new.write_text("\n".join([HEADER, ROWS[0].replace("WT-1", "WT-9")]))
    assert specfile.import_file(part, new) == 1
    assert len(read_specs(part.specs_path)) == 4
    with pytest.raises(InputError, match="already exists"):
        specfile.import_file(part, new)
    assert specfile.import_file(part, new, replace_all=True) == 1
    assert [s.id for s in read_specs(part.specs_path)] == ["WT-9"]


CELL = st.one_of(
    st.sampled_from(["", "nan", "1e400", "-0.127", "0.127", "2.5", "web_thickness",
                     "hole_diameter", "A", "P01", "WT-1", "\"", ",", "0", "1"]),
    st.text(max_size=8),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(CELL, min_size=0, max_size=19), min_size=0, max_size=6),
       header=st.sampled_from([HEADER, "id,kind", HEADER + ",x", ""]),
       raw=st.binary(max_size=40))
def test_malformed_imports_never_crash_nor_write(part: Plate, tmp_path: Path, rows, header, raw) -> None:
    import csv
    import io

    buf = io.StringIO()
    csv.writer(buf).writerows(rows)
    bad = tmp_path / "fuzz.csv"
    bad.write_bytes(header.encode() + b"\n" + buf.getvalue().encode("utf-8", "surrogatepass") + raw)
    before = part.specs_path.read_bytes()
    try:
        n = specfile.import_file(part, bad)
    except InputError as exc:
        assert exc.problems and all(str(loc).startswith(str(bad)) for loc, _ in exc.problems)
        assert part.specs_path.read_bytes() == before
    else:
        assert len(read_specs(part.specs_path)) == 3 + n
        part.specs_path.write_bytes(before)
