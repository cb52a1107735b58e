"""Hostile but fair input to the commands: a clear error naming what and where, exit 2,
nothing written, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from archive_synth import fake_specs, record_synthetic_run, true_values
from click.testing import CliRunner

from ita.archive import Archive, RunStatus
from ita.cli import main
from ita.errors import InputError
from ita.specs.io import COLUMNS, parse_specs_text

REPO = Path(__file__).resolve().parent.parent
HEADER = ",".join(COLUMNS)


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def run_cli(args: list[bytes], home: Path) -> subprocess.CompletedProcess[bytes]:
    env = dict(os.environ, PYTHONPATH=str(REPO), ITA_HOME=str(home))
    return subprocess.run([sys.executable.encode(), str(REPO / "cli.py").encode(), *args],
                          capture_output=True, env=env, timeout=300)


@pytest.mark.parametrize("command", [[b"kb", b"query", b"\xff(X)"], [b"plan", b"\xff"], [b"results", b"\xfe"],
                                     [b"report", b"\xff", b"-o", b"x.html"], [b"continue", b"\xff"],
                                     [b"monitor", b"\xff"], [b"measure", b"\xff"]])
def test_arguments_that_are_not_utf8(command, tmp_path: Path):
    proc = run_cli(command, tmp_path / "home")
    assert proc.returncode == 2, proc.stderr
    assert b"not valid UTF-8" in proc.stderr and b"Traceback" not in proc.stderr
    assert not (tmp_path / "x.html").exists()


@pytest.mark.parametrize("text,where,what", [
    (HEADER + "\n" + 'a,"unterminated\n', "f.csv:2", "unexpected end of data"),
    (HEADER + ",id\n", "f.csv:1", "header repeats column(s): id"),
    (HEADER + "\nx," + "a" * 200_000 + "\n", "f.csv:2", "field larger than field limit"),
])
def test_bad_csv_is_a_clear_error(text: str, where: str, what: str):
    with pytest.raises(InputError) as err:
        parse_specs_text(text, "f.csv")
    assert where in str(err.value) and what in str(err.value)


def test_a_byte_order_mark_is_accepted(builtin_part, tmp_path: Path):
    text = builtin_part.specs_path.read_text(encoding="utf-8")
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    result = run("spec", "validate", str(path))
    assert result.exit_code == 0, result.output


def _damaged_archive(tmp_path: Path) -> Path:
    runs = tmp_path / "runs"
    runs.mkdir()
    specs = fake_specs(60)
    with Archive.open(runs / "archive.sqlite") as archive:
        record_synthetic_run(archive, specs, true_values(specs), status=RunStatus.COMPLETED)
    data = bytearray((runs / "archive.sqlite").read_bytes())
    for i in range(4096, len(data), 5):  # every page after the first
        data[i] = 0xAB
    (runs / "archive.sqlite").write_bytes(bytes(data))
    return runs


@pytest.mark.parametrize("command", [["runs"], ["results", "last"]])
def test_a_damaged_archive_is_a_clear_error(tmp_path: Path, command):
    runs = _damaged_archive(tmp_path)
    result = run(*command, "--runs-dir", str(runs))
    assert result.exit_code == 2, result.output
    assert "error:" in result.output and "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_a_read_only_home_is_a_clear_error(tmp_path: Path, monkeypatch):
    home = tmp_path / "home"
    home.mkdir()
    home.chmod(0o500)
    monkeypatch.setenv("ITA_HOME", str(home))
    result = run("part", "info")
    assert result.exit_code == 2 and "error:" in result.output


def test_an_unwritable_output_directory(tmp_path: Path, builtin_part):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = run("spec", "export", str(blocker / "out.csv"))
    assert result.exit_code == 2
    assert "is not a directory" in result.output and str(blocker) in result.output


def _part_dir(tmp_path: Path, mesh: bytes, name: str = "m.stl") -> Path:
    part = tmp_path / "part"
    part.mkdir()
    (part / name).write_bytes(mesh)
    (part / "specs.csv").write_text(HEADER + "\n", encoding="utf-8")
    return part


def test_a_damaged_stl_is_named_as_such(tmp_path: Path):
    part = _part_dir(tmp_path, b"\x01" * 80 + (1000).to_bytes(4, "little") + b"\x00" * 100)
    result = run("part", "info", "--part", str(part))
    assert result.exit_code == 2
    assert "damaged binary STL" in result.output and str(part / "m.stl") in result.output
    assert "charset_normalizer" not in result.output


def test_nan_vertices_are_refused(tmp_path: Path):
    facet = "facet normal 0 0 1\nouter loop\nvertex {}\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
    text = "solid x\n" + facet.format("nan 0 0") + facet.format("0 inf 0") + "endsolid x\n"
    part = _part_dir(tmp_path, text.encode())
    result = run("part", "info", "--part", str(part))
    assert result.exit_code == 2
    assert "NaN or infinite" in result.output


def test_a_busy_run_suggests_a_command_that_exists(tmp_path: Path):
    from ita.archive.store import RunBusy

    specs = fake_specs(5)
    with Archive.open(tmp_path / "archive.sqlite") as archive:
        record_synthetic_run(archive, specs, true_values(specs), status=RunStatus.RUNNING)
        run_id = archive.runs()[0].id
        with pytest.raises(RunBusy) as err:
            archive.resume_run(run_id)
    assert "--force" not in str(err.value) and "or force" not in str(err.value)
    assert f"ita monitor {run_id} --stop" in str(err.value)


def test_inspect_refuses_an_asbuilt_mesh_in_other_units_before_preparing(builtin_part, tmp_path: Path):
    import shutil
    import time

    import trimesh

    copy = tmp_path / "copy"
    assert run("part", "build", "-o", str(copy)).exit_code == 0
    shutil.rmtree(copy / "truth", ignore_errors=True)
    asbuilt = trimesh.load(copy / "nominal.stl")
    asbuilt.apply_scale(0.001)                     # in metres
    asbuilt.export(copy / "asbuilt.stl")
    started = time.monotonic()
    result = run("inspect", "--part", str(copy), "--limit", "1", "--runs-dir", str(tmp_path / "runs"))
    assert result.exit_code == 2, result.output
    assert "asbuilt.stl" in result.output and "same frame and units (mm)" in result.output
    assert time.monotonic() - started < 60
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").rglob("*.sqlite"))


@pytest.mark.parametrize("command", [["part", "info"], ["spec", "remove", "X"],
                                     ["sequence", "tool", "broken", "us_probe_1"]])
def test_an_unusable_home_is_a_clear_error(tmp_path: Path, monkeypatch, command):
    """An ITA_HOME that cannot be made (here under a file; read-only behaves alike for a
    user who is not root): one error line naming the directory, exit 2."""
    (tmp_path / "file").write_text("x")
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "file" / "home"))
    result = run(*command)
    assert result.exit_code == 2, result.output
    assert f"{tmp_path / 'file' / 'home'}: Not a directory" in result.output
