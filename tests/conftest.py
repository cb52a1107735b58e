"""Shared fixtures of the Python tests.

Every test runs with a private ITA_HOME (autouse, one per session), so no test reads or
writes the user's real data; the built-in bulkhead is materialised there once.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent



def pytest_configure(config: pytest.Config) -> None:
    """hypothesis keeps no example database and no cache in the checkout: tests write only
    under their temporary directories. Ctrl-C (SIGINT) reaches the processes the tests start
    as it does at a terminal, even when pytest runs as a background job, which inherits
    SIGINT ignored (and would pass that on to every child)."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        from hypothesis import settings
        from hypothesis.configuration import set_hypothesis_home_dir
    except ImportError:
        return
    home = tempfile.mkdtemp(prefix="ita-hypothesis-")
    config.add_cleanup(lambda: shutil.rmtree(home, ignore_errors=True))
    set_hypothesis_home_dir(home)
    settings.register_profile("ita", database=None)
    settings.load_profile("ita")


@pytest.fixture(scope="session", autouse=True)
def ita_home(tmp_path_factory: pytest.TempPathFactory):
    """A fresh ITA_HOME for the whole session (the built-in part is materialised there once)."""
    home = tmp_path_factory.mktemp("ita_home")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("ITA_HOME", str(home))
        yield home


@pytest.fixture(scope="session")
def bulkhead():
    """The built-in bulkhead, generated in memory once (GeneratedPart)."""
    from ita.part.bulkhead import generate, load_params

    return generate(load_params())


@pytest.fixture(scope="session")
def builtin_part(ita_home):
    """The built-in bulkhead materialised under the session's ITA_HOME (Part)."""
    from ita.part.store import load_part

    return load_part(None)


@pytest.fixture(scope="session")
def knowledge_base():
    """The real knowledge bases, loaded once for the session (SWI has one per process)."""
    from ita.logic.bridge import KnowledgeBase

    return KnowledgeBase()


@pytest.fixture()
def run_python(tmp_path: Path, ita_home: Path):
    """Run Python code (or `cli.py` arguments) in a fresh process, with a fresh Prolog.

    Needed to load a knowledge base that differs from the real one: SWI-Prolog has one
    database per process.  The child shares the session's ITA_HOME.
    """

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        env = dict(os.environ, PYTHONPATH=str(REPO), ITA_HOME=str(ita_home))
        return subprocess.run(
            [sys.executable, *args], capture_output=True, text=True, timeout=120,
            cwd=tmp_path, env=env,
        )

    return run


@pytest.fixture()
def broken_kb(tmp_path: Path) -> Path:
    """A kb directory whose one file has a syntax error on line 3, column 11."""
    kb_dir = tmp_path / "kb"
    kb_dir.mkdir()
    (kb_dir / "broken_kb.pl").write_text(
        ":- module(broken_kb, [p/1]).\n"
        "\n"
        "p(X) :- q(X.\n"
        "q(1).\n",
        encoding="utf-8",
    )
    return kb_dir
