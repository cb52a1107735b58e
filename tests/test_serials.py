"""Each serial its own as-built part of one design (ita/part/serials.py)."""

from __future__ import annotations

import pytest

from ita.errors import InputError
from ita.part import truth
from ita.part.serials import parse_shift, serial_asbuilt


def _values(made) -> dict[str, float]:
    return truth.load_truth(made.directory).values


def test_a_serial_is_the_same_part_every_time_and_two_serials_are_two_parts(builtin_part):
    a1, a2, b = (serial_asbuilt(builtin_part, "SN-1"), serial_asbuilt(builtin_part, "SN-1"),
                 serial_asbuilt(builtin_part, "SN-2"))
    assert a1.directory == a2.directory and a1.directory != b.directory
    va, vb = _values(a1), _values(b)
    assert va == _values(a2) and va.keys() == vb.keys()
    assert sum(1 for k in va if abs(va[k] - vb[k]) > 1e-6) > 0.8 * len(va)
    from ita.specs.io import read_specs

    specs = {s.id: s for s in read_specs(builtin_part.specs_path)}
    # a process in control: no feature out of tolerance (the generator's gross errors are the first article's)
    assert all(specs[k].low_limit - 1e-9 <= v <= specs[k].high_limit + 1e-9 for k, v in va.items())
    # and not the first article's part either
    assert va != truth.load_truth(builtin_part.directory).values


def test_a_shift_moves_that_characteristic_by_delta_in_that_serial(builtin_part):
    base = _values(serial_asbuilt(builtin_part, "SN-7"))
    shifted = _values(serial_asbuilt(builtin_part, "SN-7", {"WT-P05-2": 0.25}))
    assert shifted["WT-P05-2"] == pytest.approx(base["WT-P05-2"] + 0.25, abs=1e-6)
    moved = {k for k in base if abs(shifted[k] - base[k]) > 1e-9}
    assert moved and all(k.startswith("WT-P05-") for k in moved)      # the pocket's web: its points
    with pytest.raises(InputError, match="no spec 'NOPE'"):
        serial_asbuilt(builtin_part, "SN-7", {"NOPE": 0.1})
    edge = next(s for s in base if s.startswith("ED-"))
    with pytest.raises(InputError, match="cannot be shifted"):
        serial_asbuilt(builtin_part, "SN-7", {edge: 0.1})
    assert parse_shift("WT-P05-2=-0.1") == ("WT-P05-2", -0.1)
    for bad in ("WT-P05-2", "=0.1", "WT-P05-2=abc", "WT-P05-2=nan"):
        with pytest.raises(InputError, match="--shift"):
            parse_shift(bad)


def test_inspect_refuses_a_shift_without_a_serial_and_a_bad_shift(tmp_path):
    from click.testing import CliRunner

    from ita.cli import main

    alone = CliRunner().invoke(main, ["inspect", "--shift", "WT-P05-2=0.1", "--runs-dir", str(tmp_path)])
    assert alone.exit_code == 2 and "--shift goes with --serial" in alone.output
    bad = CliRunner().invoke(main, ["inspect", "--serial", "SN-1", "--shift", "WT-P05-2", "--runs-dir",
                                    str(tmp_path)])
    assert bad.exit_code == 2 and "error: --shift" in bad.output
    assert not (tmp_path / "archive.sqlite").exists()
