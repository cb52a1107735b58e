"""Heights decided with their web's measured thickness (ita.toplevel.heights): the
substitution, its uncertainty, the floors, and a run that measures the height before or
after its web."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from ita.archive import Archive, Event, archive_path
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.toplevel.heights import EVENT_KIND, HeightPending, WebRef, decide_height
from ita.vision.context import MeshFloor


def _height_spec() -> MeasurementSpec:
    return MeasurementSpec("FH-1", K.FLANGE_HEIGHT, "F1", (0.0, 0.0, 40.0), (0, 0, 1), 40.0, -0.25, 0.25)


def test_a_pending_height_survives_the_archive() -> None:
    p = HeightPending("FH-1", "slra_1", 1.0, 2.5, 0.004, (WebRef((10.0, 2.0), 2.5, 40.03, ("WT-1", "WT-2")),),
                      40.03, 0.075, "from the frame of FH-2")
    assert HeightPending.from_event(Event(EVENT_KIND, "top", 2.5, p.to_event().payload)) == p


def test_the_measured_web_takes_the_place_of_its_nominal_and_of_its_tolerance() -> None:
    """Seen through a web 0.03 mm thicker than nominal, the height read 0.03 high; with the
    web measured it is right, and its U is the fit's and the gauge's, not the tolerance's."""
    spec = _height_spec()
    web = WebRef((10.0, 2.0), 2.5, 40.03, ("WT-1", "WT-2"))
    p = HeightPending("FH-1", "slra_1", 1.0, 2.5, 0.004, (web,), 40.03, 0.075)
    points = {"WT-1": (12.0, 2.0, 2.5), "WT-2": (90.0, 2.0, 2.5)}
    r = decide_height(p, spec, {"WT-1": (2.53, 0.002), "WT-2": (2.534, 0.002)}, points, 0.127)
    assert r.value == pytest.approx(40.06)                       # 40.03 - 2.5 + 2.53 (the nearer one)
    spread = float(np.std([2.53, 2.534], ddof=1))
    assert r.u == pytest.approx(math.hypot(0.004, math.hypot(0.002, spread)))
    assert "WT-1" in r.reason
    alone = decide_height(p, spec, {}, points, 0.127)            # not measured: nominal and tolerance
    assert alone.value == pytest.approx(40.03)
    assert alone.u == pytest.approx(math.hypot(0.004, 0.127 / math.sqrt(3)))
    assert alone.U > 5 * r.U


def test_two_webs_one_measured_keep_the_other_s_tolerance() -> None:
    spec = _height_spec()
    a = WebRef((10.0, 2.0), 2.5, 40.02, ("WT-1",))
    b = WebRef((-10.0, 2.0), 2.5, 40.00, ())
    r = decide_height(HeightPending("FH-1", None, None, None, 0.003, (a, b), 40.01, 0.05), spec,
                      {"WT-1": (2.52, 0.002)}, {"WT-1": (10.0, 0.0, 2.5)}, 0.127)
    assert r.value == pytest.approx(((40.02 - 2.5 + 2.52) + 40.00) / 2)
    assert r.u == pytest.approx(math.hypot(0.003, math.hypot(0.002, 0.127 / math.sqrt(3)) / 2))


def test_a_mesh_s_floors_are_its_flat_facets() -> None:
    """Two pocket floors at different heights beside each other are two regions; two points
    of one floor are one."""
    low = trimesh.creation.box((100.0, 100.0, 5.0), trimesh.transformations.translation_matrix((50, 50, 2.5)))
    high = trimesh.creation.box((100.0, 100.0, 8.0), trimesh.transformations.translation_matrix((150, 50, 4.0)))
    floor = MeshFloor(trimesh.util.concatenate([low, high]))
    assert floor.region(np.array([20.0, 20.0])) == floor.region(np.array([80.0, 70.0])) is not None
    assert floor.region(np.array([150.0, 50.0])) not in (None, floor.region(np.array([20.0, 20.0])))
    assert floor.height(np.array([150.0, 50.0])) == pytest.approx(8.0)


@pytest.mark.parametrize("height_first", [False, True])
def test_a_height_is_decided_with_its_web_measured_before_or_after_it(tmp_path, ita_home, builtin_part,
                                                                     height_first) -> None:
    """On the built-in bulkhead: a flange height and the web thicknesses of its floor.
    Measured after them (the probe's group first) it is decided at once; measured first
    (the SLRA's group first, the plan's order: the SLRA registers the part), it waits (an
    archive event) and is decided when the last of them is done.  Either way its value
    holds the web's measured thickness, and its U is a fraction of what the tolerance gave."""
    from ita.scoring.truth import true_values
    from ita.task import open_session
    from ita.toplevel import RunSignals, TopLevel
    from ita.toplevel.heights import web_specs

    session = open_session(None, seed=3)
    vctx = session.slra.vctx
    floors = web_specs(session.ctx.specs, vctx)
    fh = session.specs["FH-OFL03-1"]
    # the floor beside the flange: the region of the web thickness specs nearest to it
    wt = min((s for s in session.ctx.specs if s.kind is K.WEB_THICKNESS),
             key=lambda s: math.dist(s.point[:2], fh.point[:2]))
    region = vctx.web_region(np.asarray(wt.point[:2]))
    ids = [fh.id, *floors[region]]
    groups = tuple(sorted(session.plan.groups, key=lambda g: g.tool.startswith("slra") != height_first))
    session.plan = replace(session.plan, groups=groups)
    runs = tmp_path / "runs"
    with Archive.open(archive_path(runs)) as archive:
        run_id = archive.create_run("bulkhead", session.part.directory, seed=3, total=len(ids),
                                    settings={"specs": ids, "simulated": True})
        TopLevel(session, archive, run_id, RunSignals(message=None)).run()
        r = archive.result(run_id, fh.id)
        waited = [e.payload["spec"] for e in archive.events(run_id, kinds=[EVENT_KIND])]
    session.close()
    assert r is not None and r.value is not None, r
    assert waited == ([fh.id] if height_first else [])
    assert "web measured: WT-" in r.reason, r.reason
    assert r.U < 0.3 * 0.147        # the tolerance term alone made U 0.147 mm
    truth = true_values(builtin_part.directory)[fh.id]
    assert abs(r.value - truth) < r.U


def test_two_webs_read_through_one_gauge_point_share_its_error() -> None:
    """Both sides of a rib on one floor, one thickness measured: its error moves both webs
    alike, so it is not divided by sqrt 2 as two independent webs' would be."""
    spec = _height_spec()
    a = WebRef((10.0, 2.0), 2.5, 40.02, ("WT-1",))
    b = WebRef((-10.0, 2.0), 2.5, 40.00, ("WT-1",))
    r = decide_height(HeightPending("FH-1", None, None, None, 0.003, (a, b), 40.01, 0.05), spec,
                      {"WT-1": (2.52, 0.004)}, {"WT-1": (0.0, 0.0, 2.5)}, 0.127)
    assert r.u == pytest.approx(math.hypot(0.003, 0.004))
