"""Reading, writing and rejecting measurement spec files."""

from __future__ import annotations

from pathlib import Path

import pytest

from ita.errors import InputError
from ita.specs.io import COLUMNS, format_specs, read_spec_table, read_specs, write_specs
from ita.specs.model import MeasurementKind, MeasurementSpec

HEADER = ",".join(COLUMNS)
GOOD = "WT-1,web_thickness,P01,10,20,2.5,0,0,1,2.5,-0.127,0.127,A,,,,"


def write(tmp_path: Path, *rows: str, header: str = HEADER) -> Path:
    path = tmp_path / "specs.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def problems_of(path: Path) -> list[tuple[int, str, str]]:
    with pytest.raises(InputError) as info:
        read_specs(path)
    return [(loc.line, loc.field, msg) for loc, msg in info.value.problems]


def test_round_trip_preserves_every_field(tmp_path: Path) -> None:
    specs = [
        MeasurementSpec("WT-1", MeasurementKind.WEB_THICKNESS, "P01", (10.0, 20.0, 2.5),
                        (0.0, 0.0, 1.0), 2.5, -0.127, 0.127, "A"),
        MeasurementSpec("ED-7", MeasurementKind.EDGE_DISTANCE, "H07", (100.125, 3.0, 40.0),
                        (0.0, 0.0, 1.0), 12.7, -0.5, 0.5, "A|B|C", (1.0, 0.0, 0.0), "a, note"),
    ]
    path = tmp_path / "s.csv"
    write_specs(path, specs)
    assert read_specs(path) == specs
    assert read_specs(path)[1].note == "a, note"


@pytest.mark.parametrize(
    "row, field, words",
    [
        ("WT-1,web_girth,P01,10,20,2.5,0,0,1,2.5,-0.127,0.127,A,,,,", "kind", "unknown kind"),
        ("WT-1,web_thickness,P01,10,20,2.5,0,0,1,2.5,0.2,0.1,A,,,,", "lower", "not below upper"),
        ("WT-1,web_thickness,P01,10,abc,2.5,0,0,1,2.5,-0.1,0.1,A,,,,", "y", "not a number"),
        ("WT-1,web_thickness,P01,10,20,2.5,0,0,1,nan,-0.1,0.1,A,,,,", "nominal", "not a finite"),
        ("WT-1,web_thickness,P01,10,20,2.5,0,0,0,2.5,-0.1,0.1,A,,,,", "nx", "zero-length"),
        ("WT 1,web_thickness,P01,10,20,2.5,0,0,1,2.5,-0.1,0.1,A,,,,", "id", "bad id"),
        ("WT-1,web_thickness,,10,20,2.5,0,0,1,2.5,-0.1,0.1,A,,,,", "feature", "missing feature"),
        ("WT-1,web_thickness,P01,10,20,2.5,0,0,1,,-0.1,0.1,A,,,,", "nominal", "missing value"),
        ("WT-1,web_thickness,P01,10,20,2.5,0,0,1,2.5,-0.1,0.1,,,,,", "datum", "missing datum"),
        ("WT-1,edge_distance,P01,10,20,2.5,0,0,1,2.5,-0.1,0.1,A,1,,,", "dy", "missing value"),
    ],
)
def test_each_kind_of_bad_row_is_named_with_line_and_field(
    tmp_path: Path, row: str, field: str, words: str
) -> None:
    path = write(tmp_path, GOOD.replace("WT-1", "WT-0"), row)
    found = problems_of(path)
    assert any(line == 3 and f == field and words in msg for line, f, msg in found), found


def test_duplicate_id_names_both_lines(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD, "# a comment", GOOD)
    assert problems_of(path) == [(4, "id", "duplicate id 'WT-1' (first on line 2)")]


def test_every_bad_row_is_reported_not_only_the_first(tmp_path: Path) -> None:
    bad = GOOD.replace("web_thickness", "x")
    path = write(tmp_path, bad.replace("WT-1", "A1"), GOOD, bad.replace("WT-1", "A2"))
    assert [line for line, _, _ in problems_of(path)] == [2, 4]


def test_header_errors(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD, header="id,kind,feature")
    assert "lacks column" in problems_of(path)[0][2]
    path = write(tmp_path, GOOD, header=HEADER + ",colour")
    assert "unknown column" in problems_of(path)[0][2]
    empty = tmp_path / "empty.csv"
    empty.write_text("# only a comment\n")
    assert "empty" in problems_of(empty)[0][2]


def test_error_message_names_the_file(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD.replace("web_thickness", "bogus"))
    with pytest.raises(InputError) as info:
        read_specs(path)
    assert str(info.value).startswith(f"{path}:2 [kind]: unknown kind 'bogus'")


def test_missing_and_binary_files(tmp_path: Path) -> None:
    assert "not found" in problems_of(tmp_path / "nope.csv")[0][2]
    binary = tmp_path / "bin.csv"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    assert "UTF-8" in problems_of(binary)[0][2]


def test_normals_are_normalised_and_lines_kept(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD.replace("0,0,1,2.5", "0,0,3,2.5"))
    table = read_spec_table(path)
    assert table.specs[0].normal == (0.0, 0.0, 1.0)
    assert table.line_of("WT-1") == 2


def test_write_refuses_duplicates_and_leaves_file_alone(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD)
    before = path.read_bytes()
    spec = read_specs(path)[0]
    with pytest.raises(InputError):
        write_specs(path, [spec, spec])
    assert path.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_format_is_stable() -> None:
    spec = MeasurementSpec("HD-1", MeasurementKind.HOLE_DIAMETER, "H1", (1.0, 2.0, 3.0),
                           (0.0, 0.0, 1.0), 6.35, -0.05, 0.08, "A|B")
    assert format_specs([spec]).splitlines()[1] == \
        "HD-1,hole_diameter,H1,1.0,2.0,3.0,0.0,0.0,1.0,6.35,-0.05,0.08,A|B,,,,"


def test_a_crash_during_write_leaves_the_old_file_whole(tmp_path: Path, monkeypatch) -> None:
    path = write(tmp_path, GOOD)
    before = path.read_bytes()
    spec = read_specs(path)[0]

    def crash(*_args, **_kwargs):
        raise KeyboardInterrupt  # as if Ctrl-C arrived between writing and renaming

    monkeypatch.setattr("ita.files.atomic.os.replace", crash)
    with pytest.raises(KeyboardInterrupt):
        write_specs(path, [spec, spec.__class__(**{**spec.__dict__, "id": "WT-2"})])
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["specs.csv"]
