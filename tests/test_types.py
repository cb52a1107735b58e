"""Types are checked, not only written: mypy, as configured in pyproject.toml (the
default level on the whole package, the strict flags on the task, diagnosis and top
levels, the executive, the devices, the planners and the Prolog bridge), reports no
error.  Anyone can run it: `.venv/bin/mypy`.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def test_mypy_finds_no_error(tmp_path):
    mypy = shutil.which("mypy", path=str(Path(sys.executable).parent)) or shutil.which("mypy")
    if mypy is None:
        pytest.fail("mypy is not installed (it comes with the test extras: pip install -e '.[test]')")
    proc = subprocess.run([mypy, "--cache-dir", str(tmp_path / "mypy-cache")], cwd=REPO, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-6000:] + proc.stderr[-2000:]
    assert "Success: no issues found" in proc.stdout
