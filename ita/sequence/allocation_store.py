"""The two-arm allocation, kept between runs: ``ita_home()/plans/<part>@allocation.json``.

Allocating a whole bulkhead between two arms takes seconds (each arm's configurations,
its body clear of the other's, the tours); a two-arm run of the same prepared part makes
the same allocation every time, so it is stored with a digest of everything it depends
on (the one-arm plan, both arms' MKBs, the workcell, the specs, the dwell, and the
source of the packages that compute it) and reused while that digest holds.  A stored
file that is damaged, of another digest, or not of this format is a miss: the
allocation is made afresh and the file replaced (atomically).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ita.files.atomic import store_name, write_json_atomic
from ita.geometry.mkb import MeasurementKB
from ita.sequence.allocate import DWELL_S, Allocation, ArmShare, allocate
from ita.sequence.plan import PlanningContext, SequencePlan
from ita.sequence.store import plan_to_dict, plans_dir

FORMAT = 2
#: the packages whose code makes an allocation (and arranges its tours: the executive's
#: coordination): a change to any makes the stored one stale
_SOURCES = ("sequence", "kinematics", "workcell", "collision", "geometry", "executive")
_ROOT = Path(__file__).resolve().parent.parent


def allocation_path(part_name: str) -> Path:
    """Where the allocation of part `part_name` is kept."""
    return plans_dir() / f"{store_name(part_name)}@allocation.json"


def allocation_digest(ctx: PlanningContext, plan: SequencePlan, dwell_s: Mapping[str, float],
                      mkbs: Mapping[str, MeasurementKB] | None, arranged: bool = False) -> str:
    """Digest of what :func:`ita.sequence.allocate.allocate` reads (and whether its tours
    are arranged after)."""
    h = hashlib.sha256(b"arranged" if arranged else b"")
    stored = {k: v for k, v in plan_to_dict(plan).items()      # the plan, not its progress
              if k not in ("created", "build_seconds", "done", "handed_out", "history")}
    h.update(json.dumps(stored, sort_keys=True).encode())
    h.update(repr((ctx.workcell, ctx.specs_digest, ctx.cost_model.name, sorted(dwell_s.items()))).encode())
    h.update(repr(sorted((arm, m.digest) for arm, m in (mkbs or {}).items())).encode())
    for package in _SOURCES:
        for path in sorted((_ROOT / package).rglob("*.py")):
            h.update(path.relative_to(_ROOT).as_posix().encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def stored_allocation(ctx: PlanningContext, plan: SequencePlan, dwell_s: Mapping[str, float] = DWELL_S,
                      mkbs: Mapping[str, MeasurementKB] | None = None,
                      arrange: Callable[[Allocation], Allocation] | None = None) -> tuple[Allocation, bool]:
    """The allocation of ``plan`` (:func:`~ita.sequence.allocate.allocate`; then
    ``arrange``d: its tours in the order the arms run them), the stored one when current;
    and whether it was stored."""
    digest = allocation_digest(ctx, plan, dwell_s, mkbs, arranged=arrange is not None)
    path = allocation_path(ctx.part_name)
    kept = _load(path, digest)
    if kept is not None:
        return kept, True
    made = allocate(ctx, plan, dwell_s, mkbs)
    if arrange is not None:
        made = arrange(made)
    write_json_atomic(path, {"format": FORMAT, "digest": digest, **_to_dict(made)})
    return made, False


def _to_dict(a: Allocation) -> dict[str, Any]:
    return {
        "shares": [{"arm": s.arm, "groups": [[t, list(o), c] for t, o, c in s.groups], "time_s": s.time_s,
                    "count": s.count, "legs": [list(leg) for leg in s.legs], "rack_s": s.rack_s} for s in a.shares],
        "assigned": dict(a.assigned), "makespan_s": a.makespan_s, "bound_s": a.bound_s, "one_arm_s": a.one_arm_s,
        "unassigned": [[i, w] for i, w in a.unassigned], "split": a.split, "dwell_s": dict(a.dwell_s),
        "able": {arm: sorted(ids) for arm, ids in a.able.items()},
        "reaches": {arm: sorted(ids) for arm, ids in a.reaches.items()},
        "arranged": a.arranged,
    }


def _load(path: Path, digest: str) -> Allocation | None:
    """The stored allocation of that digest, or None (no file, another digest, damaged)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("format") != FORMAT or data.get("digest") != digest:
            return None
        shares = tuple(ArmShare(str(s["arm"]), tuple((str(t), tuple(map(str, o)), float(c)) for t, o, c in s["groups"]),
                                float(s["time_s"]), int(s["count"]), tuple(tuple(map(float, leg)) for leg in s["legs"]),
                                float(s["rack_s"])) for s in data["shares"])
        return Allocation(shares, {str(k): str(v) for k, v in data["assigned"].items()}, float(data["makespan_s"]),
                          float(data["bound_s"]), float(data["one_arm_s"]),
                          tuple((str(i), str(w)) for i, w in data["unassigned"]), int(data["split"]),
                          {str(k): float(v) for k, v in data["dwell_s"].items()}, {str(a): frozenset(map(str, ids)) for a, ids in data["able"].items()},
                          {str(a): frozenset(map(str, ids)) for a, ids in data["reaches"].items()},
                          str(data["arranged"]))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
