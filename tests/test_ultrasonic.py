"""The ultrasonic gauge: its physics on the as-built part, every failure reason and fault,
the measuring side's checks and decisions, and the wall between measuring code and truth."""

from __future__ import annotations

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from ita.archive import Decision, decide
from ita.kinematics import choose_nearest, ik_tool, measurement_poses
from ita.part import truth as truth_mod
from ita.sensors.ultrasonic import (
    GaugeException,
    GaugeFailure,
    GaugeSpec,
    RawEcho,
    Reading,
    UltrasonicGauge,
    check_expected,
    interpret,
    velocity_calibration,
)
from ita.sim.faults import GAUGE, Fault, FaultSet
from ita.sim.ultrasonic import ProbePhysics, TriangleIndex, UltrasonicSim
from ita.sim.world import SimWorld
from ita.specs.io import read_specs

REPO = Path(__file__).resolve().parents[1]
READY = np.array([0.0, 0.057, 0.614, 0.0, 0.114, 1.571])
PRESS = 0.0015
PROBE = "us_probe_1"


def _place(world, point_mm, normal, press_m=PRESS, tilt_deg=0.0):
    """Put the held probe's tip on a part point (pressed in), optionally tilted about its x axis."""
    tool = world.held_tool
    poses = measurement_poses(world.cell.part, np.array([point_mm]), np.array([normal]), tool,
                              standoff=-press_m)
    if tilt_deg:
        a = math.radians(tilt_deg)
        turn = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
        poses[..., :3, :3] = poses[..., :3, :3] @ turn
    q, found = choose_nearest(world.model, ik_tool(world.model, poses, tool.tcp.matrix()).flatten_batch(), READY)
    assert found[0]
    world.set_q(q[0])


@pytest.fixture(scope="module")
def part_truth(builtin_part):
    return truth_mod.load_truth(builtin_part.directory)


@pytest.fixture(scope="module")
def web_spec(builtin_part):
    return next(s for s in read_specs(builtin_part.specs_path) if s.kind.value == "web_thickness")


@pytest.fixture(scope="module")
def world(builtin_part):
    with SimWorld(part_dir=builtin_part.directory, seed=7, q0=READY) as w:
        w.attach(PROBE)
        yield w


@pytest.fixture()
def rig(world, web_spec):
    """(world, device, gauge) with the probe pressed on the first web spec; restored after."""
    with world.saved_state():
        world.faults = FaultSet()
        _place(world, web_spec.point, web_spec.normal)
        device = UltrasonicSim(world)
        yield world, device, UltrasonicGauge(device)
        world.faults = FaultSet()


# -- physics ------------------------------------------------------------------------------
def test_reading_on_the_as_built_web_is_within_its_uncertainty(rig, web_spec, part_truth):
    _, device, gauge = rig
    gauge.apply_couplant()
    true = part_truth.values[web_spec.id]
    assert device.contact().thickness_mm == pytest.approx(true, abs=1e-6)
    readings = [gauge.measure() for _ in range(20)]
    assert all(isinstance(r, Reading) and r.probe == PROBE for r in readings)
    values = np.array([r.thickness_mm for r in readings])
    assert np.all(np.abs(values - true) <= np.array([r.expanded_uncertainty for r in readings]))
    assert values.mean() - true == pytest.approx(device.velocity_bias * true, abs=0.0015)
    assert 0.0005 < values.std() < 0.005


def test_a_velocity_calibration_on_the_block_removes_the_bias_and_shrinks_u(rig, web_spec, part_truth):
    world, device, gauge = rig
    spec = gauge.spec
    true = part_truth.values[web_spec.id]
    gauge.apply_couplant()
    before = [gauge.measure() for _ in range(30)]
    device.dispense()                        # the block's own couplant; the probe reads its 10 mm step
    block = interpret(device.pulse_reference(10.0), spec)
    cal = velocity_calibration(block, 10.0, 0.0005, spec)
    assert cal is not None and cal.probe == PROBE
    assert cal.u_rel < spec.velocity_u_rel / 5          # 0.02 % instead of the data sheet's 0.15 %
    gauge.calibrate(cal)
    gauge.apply_couplant()
    after = [gauge.measure() for _ in range(30)]
    assert all(r.velocity_factor == cal.factor for r in after) and all(r.velocity_factor == 1.0 for r in before)
    err_before = np.mean([r.thickness_mm for r in before]) - true
    err_after = np.mean([r.thickness_mm for r in after]) - true
    assert abs(err_before) > 0.001 * true * 0.9        # the sim's bias is 0.1 .. 0.25 %
    assert abs(err_after) < abs(err_before) / 2 and abs(err_after) < 0.0015
    assert after[0].expanded_uncertainty < before[0].expanded_uncertainty * 0.7
    # honest: most single readings within their (smaller) U
    within = np.mean([abs(r.thickness_mm - true) <= r.expanded_uncertainty for r in after])
    assert within >= 0.8


def test_a_block_reading_far_off_the_block_calibrates_nothing():
    spec = GaugeSpec()
    doubled = Reading(20.004, 0.002, 0.5, 1.2, PROBE)
    assert velocity_calibration(doubled, 10.0, 0.0005, spec) is None
    assert velocity_calibration(Reading(10.2, 0.002, 0.5, 1.2, PROBE), 10.0, 0.0005, spec) is None
    ok = velocity_calibration(Reading(10.02, 0.002, 0.5, 1.2, PROBE), 10.0, 0.0005, spec)
    assert ok is not None and ok.factor == pytest.approx(10.0 / 10.02)


def test_each_pulse_takes_its_dwell(rig):
    world, device, gauge = rig
    t0 = world.clock.now
    gauge.apply_couplant()
    reply = gauge.measure()
    assert reply.dwell_s == device.physics.dwell_s
    assert world.clock.now - t0 == pytest.approx(device.physics.dwell_s + device.physics.dispense_s)
    assert 1.0 <= device.physics.dwell_s + device.physics.dispense_s <= 3.0


def test_velocity_bias_is_a_systematic_fraction_of_a_percent(world):
    assert 0.001 <= abs(UltrasonicSim(world).velocity_bias) <= 0.0025
    assert UltrasonicSim(world, ProbePhysics(velocity_bias=0.002)).velocity_bias == 0.002


def test_thin_section_reads_double():
    plate = trimesh.creation.box(extents=(200.0, 200.0, 0.8))
    plate.apply_translation((0.0, 0.0, 0.4))
    with SimWorld(asbuilt_mesh=plate, seed=1, q0=READY) as w:
        w.attach(PROBE)
        _place(w, (0.0, 0.0, 0.8), (0.0, 0.0, 1.0))
        device = UltrasonicSim(w, ProbePhysics(velocity_bias=0.0))
        gauge = UltrasonicGauge(device)
        gauge.apply_couplant()
        reading = gauge.measure()
        assert isinstance(reading, Reading)
        assert reading.thickness_mm == pytest.approx(1.6, abs=0.01)
        assert check_expected(reading, 0.8, 0.05).reason is GaugeFailure.DOUBLED


def test_triangle_index_finds_entry_and_back_wall():
    index = TriangleIndex(trimesh.creation.box(extents=(10.0, 10.0, 3.0)))
    dist, normals = index.hits(np.array([0.3, 0.2, 10.0]), np.array([0.0, 0.0, -1.0]), 30.0)
    np.testing.assert_allclose(dist, [8.5, 11.5])
    np.testing.assert_allclose(normals[:, 2], [1.0, -1.0])


# -- failure reasons ------------------------------------------------------------------------
def test_no_couplant_means_no_echo(rig):
    _, _, gauge = rig
    reply = gauge.measure()
    assert isinstance(reply, GaugeException) and reply.reason is GaugeFailure.NO_COUPLANT and reply.no_echo


def test_couplant_dries(rig):
    world, device, gauge = rig
    gauge.apply_couplant()
    world.clock.advance(device.physics.couplant_life_s + 1.0)
    assert gauge.measure().reason is GaugeFailure.NO_COUPLANT


def test_no_contact_when_the_tip_is_off_the_surface(rig, web_spec):
    world, _, gauge = rig
    gauge.apply_couplant()
    _place(world, web_spec.point, web_spec.normal, press_m=-0.002)
    assert gauge.measure().reason is GaugeFailure.NO_CONTACT


def test_misaligned_probe_loses_the_echo(rig, web_spec):
    world, device, gauge = rig
    gauge.apply_couplant()
    _place(world, web_spec.point, web_spec.normal, tilt_deg=2.0)
    assert isinstance(gauge.measure(), Reading)
    _place(world, web_spec.point, web_spec.normal, tilt_deg=8.0)
    assert device.contact().tilt_deg == pytest.approx(8.0, abs=0.1)
    reply = gauge.measure()
    assert reply.reason is GaugeFailure.MISALIGNED and reply.no_echo


def test_no_probe_held(rig):
    world, _, gauge = rig
    world.detach()
    assert gauge.measure().reason is GaugeFailure.NO_PROBE
    world.attach("slra_1")
    assert gauge.measure().reason is GaugeFailure.NO_PROBE


# -- faults ---------------------------------------------------------------------------------
def test_broken_probe_gives_no_echo_but_the_other_probe_works(rig, web_spec):
    world, _, gauge = rig
    world.faults = FaultSet().with_fault(Fault.BROKEN_PROBE, PROBE)
    gauge.apply_couplant()
    reply = gauge.measure()
    assert reply.reason is GaugeFailure.NO_ECHO and reply.no_echo
    world.detach()
    world.attach("us_probe_2")
    _place(world, web_spec.point, web_spec.normal)
    assert isinstance(gauge.measure(), Reading)


def test_worn_probe_reads_double(rig, web_spec, part_truth):
    world, _, gauge = rig
    world.faults = FaultSet().with_fault(Fault.WORN_PROBE, PROBE)
    gauge.apply_couplant()
    reply = gauge.measure()
    assert isinstance(reply, Reading)
    assert reply.thickness_mm == pytest.approx(2 * part_truth.values[web_spec.id], rel=0.005)
    assert reply.amplitude < 0.4
    assert check_expected(reply, web_spec.nominal, 0.127).reason is GaugeFailure.DOUBLED


def test_dry_couplant_gives_no_echo(rig):
    world, _, gauge = rig
    world.faults = FaultSet().with_fault(Fault.DRY_COUPLANT, PROBE)
    gauge.apply_couplant()
    reply = gauge.measure()
    assert reply.reason is GaugeFailure.NO_COUPLANT and reply.no_echo
    assert world.couplant == ()


def test_garbage_sensor_never_yields_a_reading(rig):
    world, _, gauge = rig
    world.faults = FaultSet().with_fault(Fault.SENSOR_GARBAGE, GAUGE)
    gauge.apply_couplant()
    replies = [gauge.measure() for _ in range(25)]
    assert all(isinstance(r, GaugeException) and r.reason is GaugeFailure.GARBAGE for r in replies)
    world.faults = FaultSet()
    assert isinstance(gauge.measure(), Reading)


def test_fault_set_values():
    faults = FaultSet().with_fault(Fault.BROKEN_PROBE, "us_probe_1").with_fault("dry_couplant")
    assert faults.has(Fault.BROKEN_PROBE, "us_probe_1") and not faults.has(Fault.BROKEN_PROBE, "us_probe_2")
    assert faults.has(Fault.DRY_COUPLANT, "anything")
    assert faults.names() == ["broken_probe@us_probe_1", "dry_couplant"]
    assert not faults.without(Fault.BROKEN_PROBE).without(Fault.DRY_COUPLANT)


# -- the measuring side ----------------------------------------------------------------------
@pytest.mark.parametrize("status, reason", [
    ("no_probe", GaugeFailure.NO_PROBE), ("no_contact", GaugeFailure.NO_CONTACT),
    ("tilt", GaugeFailure.MISALIGNED), ("no_coupling", GaugeFailure.NO_COUPLANT),
    ("no_signal", GaugeFailure.NO_ECHO), ("bogus", GaugeFailure.GARBAGE)])
def test_status_words_map_to_reasons(status, reason):
    assert interpret(RawEcho(status, dwell_s=1.0), GaugeSpec()).reason is reason


@pytest.mark.parametrize("raw", [
    RawEcho("ok", math.nan, 0.5, 1.0), RawEcho("ok", -1.0, 0.5, 1.0), RawEcho("ok", 1e5, 0.5, 1.0),
    RawEcho("ok", 2.5, 3.0, 1.0), RawEcho("ok", 2.5, 0.5, math.inf), "2.5 mm"])
def test_out_of_domain_replies_are_garbage(raw):
    assert interpret(raw, GaugeSpec()).reason is GaugeFailure.GARBAGE


def test_weak_echo_is_no_echo_and_good_echo_is_a_reading():
    spec = GaugeSpec()
    assert interpret(RawEcho("ok", 2.5, 0.01, 1.0), spec).reason is GaugeFailure.NO_ECHO
    reading = interpret(RawEcho("ok", 2.5, 0.8, 1.0, "p"), spec)
    assert reading == Reading(2.5, spec.standard_uncertainty(2.5), 0.8, 1.0, "p", 2.0)
    assert reading.expanded_uncertainty == pytest.approx(2 * math.sqrt((0.0015 * 2.5) ** 2 + 0.002**2 + 1e-6 / 12))


def test_iso_14253_decisions():
    assert decide(2.50, 0.01, 2.373, 2.627) is Decision.CONFORMS
    assert decide(2.62, 0.01, 2.373, 2.627) is Decision.UNCERTAIN
    assert decide(2.632, 0.01, 2.373, 2.627) is Decision.UNCERTAIN
    assert decide(2.64, 0.01, 2.373, 2.627) is Decision.DOES_NOT_CONFORM
    assert decide(2.36, 0.01, 2.373, 2.627) is Decision.DOES_NOT_CONFORM


# -- measuring code never reads the truth ------------------------------------------------------
def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
    return names


def test_sensor_modules_import_neither_the_simulator_nor_the_truth():
    for path in sorted((REPO / "ita" / "sensors").glob("*.py")):
        bad = {n for n in _imports(path) if n.startswith(("ita.sim", "ita.part.truth", "ita.scoring"))}
        assert not bad, f"{path.name} imports {bad}"


MEASURING = ("ita.sensors", "ita.sensors.ultrasonic", "ita.vision", "ita.geometry", "ita.planning", "ita.path",
             "ita.collision", "ita.kinematics", "ita.sequence", "ita.executive", "ita.specs", "ita.logic",
             "ita.workcell", "ita.part", "ita.archive")


def test_loading_the_measuring_code_does_not_load_the_truth():
    # ita.robot (the simulated arm's controller) and ita.devices wrap the simulator: not here
    code = (f"import sys, importlib\nfor m in {MEASURING!r}: importlib.import_module(m)\n"
            "bad = [m for m in sys.modules if m.startswith(('ita.part.truth', 'ita.sim', 'ita.scoring'))]\n"
            "print(bad); sys.exit(1 if bad else 0)\n")
    proc = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, cwd=REPO,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_reading_uncertainty_comes_from_the_gauge_spec_only():
    spec = GaugeSpec(velocity_u_rel=0.003)
    reading = interpret(RawEcho("ok", 3.0, 0.7, 1.0), spec)
    assert reading.u_mm == pytest.approx(spec.standard_uncertainty(3.0))
    assert reading.u_mm > GaugeSpec().standard_uncertainty(3.0)
