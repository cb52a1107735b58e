"""Compile ITA's numba kernels once, so a user's first command does not pay for it.

numba caches compiled code beside the sources (`cache=True`); `setup.sh` runs this after
installing, which takes a few seconds once.  Run by hand: `python -m ita.warmup`.
The `default` ordering is a library (fast-tsp) and needs no compiling; `classic` does.
"""

from __future__ import annotations

import time

import numpy as np


def warm_tours() -> None:
    """Compile the classic ordering's kernels (closed tours and open paths, with and without coordinates)."""
    from ita.sequence.tour import solve_tour

    rng = np.random.default_rng(0)
    coords = rng.random((12, 2))
    cost = np.linalg.norm(coords[:, None] - coords[None], axis=-1)
    solve_tour(cost, method="classic", coords=coords)
    solve_tour(cost, method="classic", start=0)


def main() -> None:
    t0 = time.perf_counter()
    warm_tours()
    print(f"[setup] compiled the ordering kernels in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
