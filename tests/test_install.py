"""A plain (non-editable) install finds prolog/, kb/ and bulkhead/ inside the package."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    pytest.importorskip("hatchling", reason="hatchling (test extra) builds the wheel offline")
    work = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(work / "dist"), str(ROOT)],
        check=True, capture_output=True, timeout=300,
    )
    wheel = next((work / "dist").glob("ita-*.whl"))
    target = work / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
        check=True, capture_output=True, timeout=300,
    )
    return target


def run_installed(site: Path, code: str, cwd: Path) -> str:
    env = {**os.environ, "PYTHONPATH": str(site)}
    out = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_wheel_carries_the_resources(installed: Path, tmp_path: Path) -> None:
    code = ("from ita.paths import resource_dir\n"
            "for n in ('prolog', 'kb', 'bulkhead'):\n"
            "    d = resource_dir(n); print(n, d, len(list(d.iterdir())))\n")
    lines = run_installed(installed, code, tmp_path).splitlines()
    for line in lines:
        name, path, count = line.split()
        assert Path(path).is_relative_to(installed / "ita" / "_resources"), line
        assert int(count) > 0, line
    assert len(lines) == 3


def test_installed_ita_answers_kb_queries_from_any_directory(installed: Path, tmp_path: Path) -> None:
    code = ("import sys\nfrom ita.cli import main\n"
            "sys.argv = ['ita', 'kb', 'query', 'type(T, us_tool)']\nmain()\n")
    env = {**os.environ, "PYTHONPATH": str(installed), "ITA_HOME": str(tmp_path / "home")}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "us_probe_1" in out.stdout and "us_probe_2" in out.stdout
    assert str(ROOT) not in out.stdout + out.stderr
