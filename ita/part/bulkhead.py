"""The parametric F-15-like bulkhead: parameters in, nominal mesh, features and specs out.

`generate(params)` is pure and deterministic: the same parameters (including the seed)
give the same mesh, features and specs, bit for bit.  The seed decides which pockets get
lightening holes and where the web-thickness points fall; the as-built part is drawn
separately (and elsewhere) from the same seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ita.part.layout import lay_out
from ita.part.mesh import build_mesh
from ita.part.model import Feature
from ita.part.params import BulkheadParams
from ita.part.specgen import make_specs
from ita.paths import resource_dir
from ita.specs.model import MeasurementSpec

__all__ = ["BulkheadParams", "GeneratedPart", "default_params_path", "generate", "load_params"]


@dataclass(frozen=True, eq=False)
class GeneratedPart:
    """A generated nominal part: mesh (trimesh, mm), features and measurement specs."""

    params: BulkheadParams
    mesh: trimesh.Trimesh
    features: tuple[Feature, ...]
    specs: tuple[MeasurementSpec, ...]


def default_params_path() -> Path:
    """The built-in bulkhead's parameter file (bulkhead/part.toml)."""
    return resource_dir("bulkhead") / "part.toml"


def load_params(path: Path | None = None) -> BulkheadParams:
    """Parameters from `path` (default: the built-in part.toml); InputError when bad."""
    return BulkheadParams.load(path if path is not None else default_params_path())


def generate(params: BulkheadParams) -> GeneratedPart:
    """The nominal bulkhead of `params`: a watertight mesh, its features and ~1000 specs."""
    rng = np.random.default_rng(params.part.seed)
    layout = lay_out(params, rng)
    specs = make_specs(layout, params, rng)
    return GeneratedPart(params, build_mesh(layout.features), layout.features, tuple(specs))
