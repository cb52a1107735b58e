"""TSPLIB reading: EUC_2D files, nint distances, errors naming file and line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ita.errors import InputError
from ita.sequence.tsplib import euc_2d_matrix, parse_tsplib, read_tsplib

TSPLIB = Path(__file__).resolve().parents[1].parent / "shared" / "tsplib"
needs_tsplib = pytest.mark.skipif(not (TSPLIB / "berlin52.tsp").exists(),
                                  reason=f"TSPLIB instances not found in {TSPLIB}")

GOOD = """NAME: tiny
TYPE: TSP
COMMENT: four corners
DIMENSION: 4
EDGE_WEIGHT_TYPE : EUC_2D
NODE_COORD_SECTION
1 0 0
3 3 4.4
2 3 0
4 0 4
EOF
"""


def test_parse_orders_nodes_by_id_and_rounds_distances():
    p = parse_tsplib(GOOD, "tiny.tsp")
    assert p.name == "tiny" and p.dimension == 4
    assert p.coords[2].tolist() == [3.0, 4.4]
    D = p.matrix()
    assert D[0, 2] == 5.0  # sqrt(9 + 19.36) = 5.33 -> 5
    assert D[1, 2] == 4.0  # 4.4 -> nint 4
    assert np.array_equal(D, D.T) and np.all(np.diag(D) == 0)


def test_nint_rounds_half_up():
    assert euc_2d_matrix(np.array([[0.0, 0.0], [2.5, 0.0]]))[0, 1] == 3.0


@pytest.mark.parametrize("text, line, words", [
    (GOOD.replace("EUC_2D", "GEO"), 5, "unsupported EDGE_WEIGHT_TYPE GEO"),
    (GOOD.replace("TYPE: TSP", "TYPE: ATSP"), 2, "unsupported TYPE"),
    (GOOD.replace("3 3 4.4", "3 3 x"), 8, "not numbers"),
    (GOOD.replace("3 3 4.4", "3 3"), 8, "3 fields"),
    (GOOD.replace("4 0 4", "2 0 4"), 10, "duplicate node id 2"),
    (GOOD.replace("DIMENSION: 4", "DIMENSION: four"), 4, "not an integer"),
    (GOOD.replace("DIMENSION: 4", "DIMENSION: 5"), 6, "DIMENSION says 5"),
    (GOOD.replace("NODE_COORD_SECTION", "EDGE_WEIGHT_SECTION"), 6, "unsupported section"),
])
def test_errors_name_file_and_line(text, line, words):
    with pytest.raises(InputError) as err:
        parse_tsplib(text, "bad.tsp")
    assert f"bad.tsp:{line}: " in str(err.value)
    assert words in str(err.value)


def test_missing_parts_are_reported():
    with pytest.raises(InputError, match="missing DIMENSION"):
        parse_tsplib(GOOD.replace("DIMENSION: 4\n", ""), "x.tsp")
    with pytest.raises(InputError, match="missing NODE_COORD_SECTION"):
        parse_tsplib(GOOD.split("NODE_COORD_SECTION")[0], "x.tsp")


def test_unreadable_file(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_tsplib(tmp_path / "nope.tsp")


@needs_tsplib
def test_reads_every_shared_instance():
    for path in sorted(TSPLIB.glob("*.tsp")):
        p = read_tsplib(path)
        assert p.dimension == p.coords.shape[0] >= 52
        assert p.edge_weight_type == "EUC_2D"
