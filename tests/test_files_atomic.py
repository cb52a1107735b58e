"""Writes that never destroy (ita.files.atomic) and updates that are never lost."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.errors import InputError
from ita.files.atomic import locked, output_path, write_atomic

REPO = Path(__file__).resolve().parent.parent


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def test_writes_a_new_file_and_replaces_a_regular_one(tmp_path: Path):
    target = tmp_path / "out.txt"
    assert write_atomic(target, "one") == target
    target.chmod(0o640)
    write_atomic(target, b"two")
    assert target.read_bytes() == b"two"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640  # the mode of the file replaced
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]  # no temporary left


def test_refuses_a_fifo_and_a_link_to_one(tmp_path: Path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    link = tmp_path / "link"
    link.symlink_to(fifo)
    for path in (fifo, link):
        with pytest.raises(InputError, match="FIFO, not a regular file"):
            write_atomic(path, "x", what="-o")
    assert stat.S_ISFIFO(fifo.stat().st_mode) and link.is_symlink()


def test_refuses_a_directory_and_an_empty_name(tmp_path: Path):
    with pytest.raises(InputError, match="a directory, not a regular file"):
        write_atomic(tmp_path, "x")
    for empty in ("", "  "):
        with pytest.raises(InputError, match="empty file name"):
            write_atomic(empty, "x")


def test_a_link_to_a_regular_file_writes_through_it(tmp_path: Path):
    real = tmp_path / "real.txt"
    real.write_text("old")
    link = tmp_path / "link.txt"
    link.symlink_to(real)
    assert write_atomic(link, "new") == real
    assert link.is_symlink() and real.read_text() == "new"


def test_missing_directory_made_only_when_asked(tmp_path: Path):
    target = tmp_path / "a" / "b" / "out.txt"
    with pytest.raises(InputError, match="does not exist"):
        write_atomic(target, "x")
    assert not (tmp_path / "a").exists()
    write_atomic(target, "x", make_dirs=True)
    assert target.read_text() == "x"


def test_a_failing_writer_leaves_the_target_alone(tmp_path: Path):
    from ita.files.atomic import write_with

    target = tmp_path / "keep.txt"
    target.write_text("precious")

    def boom(tmp: Path) -> None:
        tmp.write_text("half")
        raise RuntimeError("writer failed")

    with pytest.raises(RuntimeError):
        write_with(target, boom)
    assert target.read_text() == "precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_output_path_of_a_file_in_a_file(tmp_path: Path):
    (tmp_path / "plain").write_text("x")
    with pytest.raises(InputError, match="is not a directory"):
        output_path(tmp_path / "plain" / "out.txt")


def test_lock_is_exclusive_between_processes(tmp_path: Path):
    store = tmp_path / "store.txt"
    code = (
        "import sys, time; from pathlib import Path; from ita.files.atomic import locked\n"
        f"p = Path({str(store)!r})\n"
        "with locked(p):\n"
        "    n = int(p.read_text()) if p.exists() else 0\n"
        "    time.sleep(0.05)\n"
        "    p.write_text(str(n + 1))\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env) for _ in range(4)]
    assert all(p.wait(timeout=60) == 0 for p in procs)
    assert store.read_text() == "4"
    with locked(store):
        pass


# -- the commands ------------------------------------------------------------------------

@pytest.fixture
def copy(builtin_part, tmp_path: Path) -> Path:
    out = tmp_path / "bulkhead"
    assert run("part", "build", "-o", str(out)).exit_code == 0
    return out


def test_spec_export_refuses_a_fifo(copy: Path, tmp_path: Path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    result = run("spec", "export", str(fifo), "--part", str(copy))
    assert result.exit_code == 2
    assert "not a regular file" in result.output and str(fifo) in result.output
    assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_spec_export_to_a_missing_directory(copy: Path, tmp_path: Path):
    target = tmp_path / "new" / "specs.csv"
    result = run("spec", "export", str(target), "--part", str(copy))
    assert result.exit_code == 2 and "does not exist" in result.output
    assert not target.parent.exists()
    assert run("spec", "export", str(target), "--mkdir", "--part", str(copy)).exit_code == 0
    assert target.read_text().startswith("id,")


def test_part_render_writes_exactly_the_name_given(builtin_part, tmp_path: Path):
    out = tmp_path / "picture"
    result = run("part", "render", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (tmp_path / "picture.png").exists()
    assert f"wrote {out}" in result.output


def test_report_to_an_empty_name_is_a_clear_error(tmp_path: Path):
    result = run("report", "last", "-o", "")
    assert result.exit_code == 2
    assert "empty file name" in result.output and "Traceback" not in result.output


def test_four_concurrent_spec_adds_give_four_specs(copy: Path):
    web = json.loads(run("spec", "list", "--json", "--kind", "web_thickness", "--part", str(copy)).stdout)[0]
    point = ",".join(str(c) for c in web["point"])
    normal = ",".join(str(c) for c in web["normal"])
    env = dict(os.environ, PYTHONPATH=str(REPO))

    def add(i: int) -> subprocess.Popen:
        return subprocess.Popen(
            [sys.executable, str(REPO / "cli.py"), "spec", "add", "--id", f"WT-PAR-{i}", "--kind",
             "web_thickness", "--feature", web["feature"], "--point", point, "--normal", normal,
             "--nominal", "2.5", "--lower", "-0.127", "--upper", "0.127", "--datum", "A",
             "--part", str(copy)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)

    procs = [add(i) for i in range(4)]
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err.decode()
    ids = {s["id"] for s in json.loads(run("spec", "list", "--json", "--part", str(copy)).stdout)}
    assert {f"WT-PAR-{i}" for i in range(4)} <= ids


def test_report_refuses_a_fifo_before_any_work(tmp_path: Path):
    fifo = tmp_path / "r.html"
    os.mkfifo(fifo)
    result = run("report", "last", "-o", str(fifo), "--runs-dir", str(tmp_path / "runs"))
    assert result.exit_code == 2
    assert "FIFO, not a regular file" in result.output and str(fifo) in result.output
    assert stat.S_ISFIFO(fifo.stat().st_mode)
