"""Tool poses that take a measurement: where the tool's TCP frame must be, in the world.

Conventions.  A measurement spec gives a point (mm) and an outward unit normal in the PART
frame; the workcell's `PartPlacement` maps both to the world (m).  The TCP frame of a
tool (`ToolSpec.tcp`, in the flange frame) has its z axis along the probe's tip axis or
the SLRA's optical axis, pointing INTO the surface.  So the tool pose for a measurement
is the TCP frame with

* z = -normal;
* origin = point + standoff * normal: the probe's tip on the point (standoff 0), or the
  SLRA's optical centre on the normal at its standoff (the nominal one by default);
* x = cos(roll) e1 + sin(roll) e2, y = z x x, where e1 is horizontal, e1 = unit(up x z)
  with up the world +z (world +y instead when z is within 2.6 deg of vertical) and
  e2 = z x e1: roll 0 puts the tool's y axis as near to world up as it can be.

A straight tool (the SLRA) looks the same at every roll; its roll is still a free choice
of the arm's j6 and the SLRA's scan direction.  The bent ultrasonic probe's flange, and so
the wrist centre, circles the normal as the roll turns, which is why several rolls are
sampled: `measurement_poses` returns candidates (n, k, 4, 4) for `ik.ik_tool`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ita.workcell.frames import unit_rows
from ita.workcell.model import PartPlacement, ToolSpec

FloatArray = NDArray[np.float64]
DEFAULT_ROLLS = 12
_NEAR_VERTICAL = 0.999


def roll_angles(count: int = DEFAULT_ROLLS) -> FloatArray:
    """Rolls (count,) rad evenly over a turn, starting at 0."""
    if count < 1:
        raise ValueError(f"roll count must be >= 1, got {count}")
    return np.arange(count, dtype=np.float64) * (2.0 * np.pi / count)


def surface_frames(points_m: ArrayLike, normals: ArrayLike, rolls: ArrayLike, standoff: float = 0.0) -> FloatArray:
    """TCP poses (n, k, 4, 4) looking along -normals (n, 3) at world points (n, 3) (m), at
    `standoff` (m) off the surface along the normal, for each roll (k,) rad."""
    p = np.atleast_2d(np.asarray(points_m, dtype=float))
    z = -unit_rows(normals)
    r = np.atleast_1d(np.asarray(rolls, dtype=float))
    up = np.where(np.abs(z[:, 2:3]) > _NEAR_VERTICAL, np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    e1 = unit_rows(np.cross(up, z))
    e2 = np.cross(z, e1)
    c, s = np.cos(r)[None, :, None], np.sin(r)[None, :, None]
    x = c * e1[:, None, :] + s * e2[:, None, :]                       # (n, k, 3)
    zk = np.broadcast_to(z[:, None, :], x.shape)
    y = np.cross(zk, x)
    out = np.zeros((len(p), len(r), 4, 4))
    out[..., :3, 0], out[..., :3, 1], out[..., :3, 2] = x, y, zk
    out[..., :3, 3] = (p - standoff * z)[:, None, :]
    out[..., 3, 3] = 1.0
    return out


def measurement_poses(
    placement: PartPlacement,
    points_mm: ArrayLike,
    normals: ArrayLike,
    tool: ToolSpec,
    rolls: int | ArrayLike = DEFAULT_ROLLS,
    standoff: float | None = None,
) -> FloatArray:
    """Candidate world TCP poses (n, k, 4, 4) of `tool` for specs at part points (n, 3) mm
    with outward part normals (n, 3).

    rolls: a count (evenly over a turn, see `roll_angles`) or the angles (k,) rad.
    standoff: metres along the normal; None takes the tool's nominal standoff (0 for the
    contact probe, whose tip then sits on the point).
    """
    angles = roll_angles(int(np.asarray(rolls))) if np.ndim(rolls) == 0 else np.asarray(rolls, dtype=float)
    points = placement.to_world(np.asarray(points_mm, dtype=float).reshape(-1, 3))
    world_normals = placement.normals_to_world(np.asarray(normals, dtype=float).reshape(-1, 3))
    distance = tool.standoff_nominal if standoff is None else float(standoff)
    return surface_frames(points, world_normals, angles, distance)


def approach_poses(tool_poses: ArrayLike, distance: float) -> FloatArray:
    """The poses (..., 4, 4) backed off by `distance` (m) along their own -z: off the surface."""
    out = np.array(tool_poses, dtype=float)
    out[..., :3, 3] -= distance * out[..., :3, 2]
    return out


def flange_of_tool(tool_poses: ArrayLike, tool: ToolSpec) -> FloatArray:
    """World flange poses (..., 4, 4) that put `tool`'s TCP at tool_poses (..., 4, 4)."""
    return np.asarray(tool_poses, dtype=float) @ np.linalg.inv(tool.tcp.matrix())
