"""Shared fixtures: a private ITA_HOME per session, and the bulkhead generated once."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
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
