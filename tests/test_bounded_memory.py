"""Big inputs in bounded memory: spec validation in chunks, a TSP size limit."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.errors import InputError
from ita.sequence.tsplib import MAX_NODES, euc_2d_matrix, parse_tsplib
from ita.specs.validate import surface_distances

REPO = Path(__file__).resolve().parent.parent


def test_chunked_surface_distances_equal_one_query(builtin_part):
    rng = np.random.default_rng(3)
    lo, hi = builtin_part.mesh.bounds
    points = rng.uniform(lo, hi, size=(300, 3))
    whole = surface_distances(builtin_part.mesh, points, chunk=10_000)
    assert np.allclose(surface_distances(builtin_part.mesh, points, chunk=7), whole)
    assert surface_distances(builtin_part.mesh, np.zeros((0, 3))).shape == (0,)


def _tsp(n: int, coord: str = "1 2") -> str:
    nodes = "\n".join(f"{i} {coord}" for i in range(1, n + 1))
    return f"NAME: t\nTYPE: TSP\nDIMENSION: {n}\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n{nodes}\nEOF\n"


def test_tsp_larger_than_the_limit_is_refused_before_reading_nodes(tmp_path: Path):
    path = tmp_path / "big.tsp"
    path.write_text(_tsp(3).replace("DIMENSION: 3", "DIMENSION: 100000"))
    result = CliRunner().invoke(main, ["sequence", "tsp", str(path)])
    assert result.exit_code == 2
    assert f"{path}:3" in result.output and f"{MAX_NODES:,} nodes" in result.output
    assert "5,000 nodes" in CliRunner().invoke(main, ["sequence", "tsp", "--help"]).output.replace("\n  ", " ")


def test_tsp_coordinates_out_of_range_are_a_clear_error():
    with pytest.raises(InputError, match="coordinate out of range"):
        parse_tsplib(_tsp(3, "1e308 1e308"), "huge.tsp")


def test_distance_matrix_matches_the_tsplib_rule():
    xy = np.array([[0.0, 0.0], [3.0, 4.0], [1.0, 1.0]])
    assert euc_2d_matrix(xy).tolist() == [[0, 5, 1], [5, 0, 4], [1, 4, 0]]


@pytest.mark.slow
def test_a_million_spec_rows_validate_in_under_2_gb(builtin_part, tmp_path: Path, ita_home: Path):
    lines = builtin_part.specs_path.read_text(encoding="utf-8").splitlines()
    header, body = lines[0], lines[1:]
    big = tmp_path / "big.csv"
    with big.open("w", encoding="utf-8") as out:
        out.write(header + "\n")
        for i in range(1_000_000):
            out.write(f"BIG-{i}," + body[i % len(body)].split(",", 1)[1] + "\n")
    env = dict(os.environ, PYTHONPATH=str(REPO), ITA_HOME=str(ita_home))
    code = ("import resource, sys\n"
            "from ita.cli import main\n"
            "try:\n"
            f"    main(['spec', 'validate', {str(big)!r}])\n"
            "except SystemExit as exc:\n"
            "    status = exc.code\n"
            "print('peak_kib', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\n"
            "sys.exit(status)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=3600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "1000000 specs valid" in proc.stdout
    peak_kib = int(proc.stderr.split("peak_kib")[-1].split()[0])
    assert peak_kib < 2 * 1024 * 1024, f"peak {peak_kib / 1024:.0f} MiB"
