"""Read and check `workcell.toml` and the arm's URDF into a `Workcell`.

Every problem found is reported at once as an `InputError` naming the file and the field
(e.g. ``workcell.toml [tool[slra_1].weight_kg]: must be > 0``).  The URDF is read with
`xml.etree`; pybullet is not needed.
"""

from __future__ import annotations

import math
import re
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ita.errors import InputError, Location
from ita.paths import builtin_dir, resource_dir
from ita.specs.model import Tool
from ita.workcell import frames
from ita.workcell.model import (
    HOME_Q,
    PROBE_HOLDER_RADIUS,
    PROBE_SHAFT_RADIUS,
    RACK_APPROACH_M,
    ArmKinematics,
    ArmSpec,
    Box,
    JointLimits,
    PartPlacement,
    Pose,
    Rack,
    RackSlot,
    ReachParams,
    Stations,
    ToolSpec,
    Vec3,
    Workcell,
)

ARM_JOINTS = ("j1", "j2", "j3", "j4", "j5", "j6")
# The axis each joint must turn about, in its parent link's frame (see ArmKinematics).
_JOINT_AXES = {"j1": (0, 0, 1), "j2": (0, 1, 0), "j3": (0, 1, 0), "j4": (1, 0, 0), "j5": (0, 1, 0), "j6": (1, 0, 0)}
_TOL = 1e-6


def default_workcell_path() -> Path:
    """The built-in workcell: `bulkhead/workcell.toml`."""
    return resource_dir("bulkhead") / "workcell.toml"


def load_workcell(path: Path | None = None) -> Workcell:
    """Load and check a workcell file (None: the built-in one) and the URDF it names.

    Raises InputError listing every bad or missing field with its file.
    """
    path = Path(path) if path is not None else default_workcell_path()
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError([(Location(str(path)), f"cannot read workcell file: {exc.strerror or exc}")]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        match = re.search(r"at line (\d+), column (\d+)", str(exc))
        line, col = (int(match.group(1)), int(match.group(2))) if match else (0, 0)
        raise InputError([(Location(str(path), line, col), f"TOML syntax: {exc}")]) from None
    reader = _Reader(path)
    workcell = _read_workcell(reader, data, path)
    reader.raise_if_problems()
    assert workcell is not None
    return workcell


class _Reader:
    """Typed access to TOML values that records problems instead of stopping at the first."""

    def __init__(self, path: Path):
        self.path = path
        self.problems: list[tuple[Location, str]] = []

    def fail(self, field: str, message: str, path: Path | None = None) -> None:
        self.problems.append((Location(str(path or self.path), field=field), message))

    def raise_if_problems(self) -> None:
        if self.problems:
            raise InputError(self.problems)

    def table(self, data: dict[str, Any], key: str, field: str) -> dict[str, Any]:
        value = data.get(key)
        if not isinstance(value, dict):
            self.fail(field, "missing table" if value is None else "must be a table")
            return {}
        return value

    def tables(self, data: dict[str, Any], key: str, field: str) -> list[dict[str, Any]]:
        value = data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            self.fail(field, "must be an array of tables ([[...]])")
            return []
        return value

    def text(self, data: dict[str, Any], key: str, field: str) -> str:
        value = data.get(key)
        if not isinstance(value, str) or not value.strip():
            self.fail(field, "missing" if value is None else "must be a non-empty string")
            return ""
        return value.strip()

    def number(
        self, data: dict[str, Any], key: str, field: str, *, low: float | None = None,
        high: float | None = None, strict_low: bool = False, default: float | None = None,
    ) -> float:
        value = data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(field, "missing" if value is None else f"must be a finite number, got {value!r}")
            return 0.0 if low is None else max(low, 0.0)
        value = float(value)
        if low is not None and (value <= low if strict_low else value < low):
            self.fail(field, f"must be {'>' if strict_low else '>='} {low:g}, got {value:g}")
        if high is not None and value > high:
            self.fail(field, f"must be <= {high:g}, got {value:g}")
        return value

    def vector(
        self, data: dict[str, Any], key: str, field: str, n: int = 3, *, positive: bool = False,
        nonnegative: bool = False,
    ) -> tuple[float, ...]:
        value = data.get(key)
        if (
            not isinstance(value, list) or len(value) != n
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        ):
            self.fail(field, "missing" if value is None else f"must be a list of {n} finite numbers, got {value!r}")
            return (1.0,) * n
        out = tuple(float(v) for v in value)
        if positive and any(v <= 0 for v in out):
            self.fail(field, f"all values must be > 0, got {list(out)}")
        if nonnegative and any(v < 0 for v in out):
            self.fail(field, f"all values must be >= 0, got {list(out)}")
        return out

    def vec3(self, data: dict[str, Any], key: str, field: str, *, positive: bool = False,
             nonnegative: bool = False) -> Vec3:
        x, y, z = self.vector(data, key, field, 3, positive=positive, nonnegative=nonnegative)
        return (x, y, z)

    def vec2(self, data: dict[str, Any], key: str, field: str, *, positive: bool = False,
             nonnegative: bool = False) -> tuple[float, float]:
        x, y = self.vector(data, key, field, 2, positive=positive, nonnegative=nonnegative)
        return (x, y)

    def pose(self, data: dict[str, Any], field: str, position_key: str = "center",
             rpy_key: str = "rpy_deg") -> Pose:
        position = self.vec3(data, position_key, f"{field}.{position_key}")
        rpy = self.vec3(data, rpy_key, f"{field}.{rpy_key}") if rpy_key in data else (0.0, 0.0, 0.0)
        roll, pitch, yaw = (math.radians(a) for a in rpy)
        return Pose.from_rpy(position, (roll, pitch, yaw))

    def box(self, data: dict[str, Any], field: str, name: str | None = None) -> Box:
        box_name = name if name is not None else self.text(data, "name", f"{field}.name")
        pose = self.pose(data, field)
        size = self.vec3(data, "size", f"{field}.size", positive=True)
        return Box(box_name, pose, size)

    def boxes(self, data: dict[str, Any], key: str, within: str = "") -> tuple[Box, ...]:
        out = []
        for i, entry in enumerate(self.tables(data, key, within + key)):
            label = entry.get("name") if isinstance(entry.get("name"), str) else i
            out.append(self.box(entry, f"{within}{key}[{label}]"))
        return tuple(out)


def _read_workcell(r: _Reader, data: dict[str, Any], path: Path) -> Workcell | None:
    robot = r.table(data, "robot", "robot")
    arm = _read_arm(r, robot, path.parent)
    part = _read_part(r, r.table(data, "part", "part"))
    tools = _read_tools(r, data, arm.payload_kg if arm else 0.0)
    rack = _read_rack(r, r.table(data, "rack", "rack"), {t.name for t in tools})
    fixture = r.boxes(data, "fixture")
    if not fixture:
        r.fail("fixture", "at least one [[fixture]] box is needed")
    reach = _read_reach(r, r.table(data, "reach", "reach"))
    second, second_pedestal = _read_second_arm(r, data, robot, path.parent, arm)
    second_stations = _read_second_stations(r, data) if second is not None else None
    cell = Workcell(
        source=path,
        arm=arm,  # type: ignore[arg-type]
        part=part,
        fixture=fixture,
        rack=rack,
        tools=tools,
        couplant_station=r.box(r.table(data, "couplant_station", "couplant_station"), "couplant_station", "couplant_station"),
        cal_block=r.box(r.table(data, "cal_block", "cal_block"), "cal_block", "cal_block"),
        floor=r.box(r.table(data, "floor", "floor"), "floor", "floor"),
        pedestal=r.box(r.table(data, "pedestal", "pedestal"), "pedestal", "pedestal"),
        stands=r.boxes(data, "stand"),
        fence=r.boxes(data, "fence"),
        reach=reach,
        second_arm=second,
        second_pedestal=second_pedestal,
        second_stations=second_stations,
    )
    _check_unique_names(r, cell)
    if second is not None and second.name == cell.arm.name:
        r.fail("robot_b.name", f"the second arm needs a name of its own (both are {second.name!r})")
    return cell


def _read_second_arm(r: _Reader, data: dict[str, Any], robot: dict[str, Any], base_dir: Path,
                     first: ArmSpec | None) -> tuple[ArmSpec | None, Box | None]:
    """The optional second arm, ``[robot_b]``: its own name, base pose and pedestal
    (``[robot_b.pedestal]``); any other key it does not give is the first arm's (the same
    model file is read once: its problems are the first arm's)."""
    if "robot_b" not in data:
        return None, None
    own = r.table(data, "robot_b", "robot_b")
    for key in ("name", "base_position", "base_rpy_deg"):
        if key not in own:
            r.fail(f"robot_b.{key}", "the second arm needs its own name and base pose")
    merged = {**{k: v for k, v in robot.items() if k not in ("name", "base_position", "base_rpy_deg")},
              **{k: v for k, v in own.items() if k not in _SECOND_ARM_EQUIPMENT}}
    same_model = set(own) <= {"name", "base_position", "base_rpy_deg", "home_rad", "tool_classes",
                              *_SECOND_ARM_EQUIPMENT}
    if same_model and first is None:
        return None, None
    if same_model and first is not None:
        base = r.pose(own, "robot_b", position_key="base_position", rpy_key="base_rpy_deg")
        home = (r.vector(merged, "home_rad", "robot_b.home_rad", n=len(ARM_JOINTS))
                if "home_rad" in merged else first.home)
        arm: ArmSpec | None = replace(first, name=r.text(own, "name", "robot_b.name"), base=base, home=tuple(home),
                                      tool_classes=_tool_classes(r, own, "robot_b") if "tool_classes" in own
                                      else first.tool_classes)
    else:
        arm = _read_arm(r, merged, base_dir, table="robot_b")
    pedestal = r.box(r.table(own, "pedestal", "robot_b.pedestal"), "robot_b.pedestal", f"pedestal_{own.get('name', 'b')}")
    return arm, pedestal


_SECOND_ARM_EQUIPMENT = ("pedestal", "couplant_station", "cal_block", "stand")   # [robot_b.*] tables, not arm keys


def _read_second_stations(r: _Reader, data: dict[str, Any]) -> Stations | None:
    """The second arm's own couplant station and calibration block
    (``[robot_b.couplant_station]``, ``[robot_b.cal_block]``, ``[[robot_b.stand]]``), both
    or neither: without them it shares the first arm's."""
    own = data.get("robot_b")
    if not isinstance(own, dict) or ("couplant_station" not in own and "cal_block" not in own):
        return None
    if not ("couplant_station" in own and "cal_block" in own):
        missing = "cal_block" if "couplant_station" in own else "couplant_station"
        r.fail(f"robot_b.{missing}", "the second arm's own stations are a couplant station and a calibration "
                                     "block, both (or neither: it shares the first arm's)")
        return None
    return Stations(
        couplant_station=r.box(r.table(own, "couplant_station", "robot_b.couplant_station"),
                               "robot_b.couplant_station", "couplant_station"),
        cal_block=r.box(r.table(own, "cal_block", "robot_b.cal_block"), "robot_b.cal_block", "cal_block"),
        stands=r.boxes(own, "stand", within="robot_b."),
    )


def _read_arm(r: _Reader, robot: dict[str, Any], base_dir: Path, table: str = "robot") -> ArmSpec | None:
    name = r.text(robot, "name", f"{table}.name")
    urdf_name = r.text(robot, "urdf", f"{table}.urdf")
    flange = r.text(robot, "flange_link", f"{table}.flange_link")
    base = r.pose(robot, table, position_key="base_position", rpy_key="base_rpy_deg")
    payload = r.number(robot, "payload_kg", f"{table}.payload_kg", low=0.0, strict_low=True)
    repeat_mm = r.number(robot, "repeatability_mm", f"{table}.repeatability_mm", low=0.0, strict_low=True)
    speed = r.number(robot, "max_tool_speed", f"{table}.max_tool_speed", low=0.0, strict_low=True, high=10.0)
    accel = r.vector(robot, "acceleration", f"{table}.acceleration", n=len(ARM_JOINTS), positive=True)
    home = r.vector(robot, "home_rad", f"{table}.home_rad", n=len(ARM_JOINTS)) if "home_rad" in robot else HOME_Q
    if not urdf_name:
        return None
    urdf = (base_dir / urdf_name).resolve()
    parsed = _read_urdf(r, urdf, flange)
    if parsed is None:
        return None
    limits, kinematics = parsed
    joints = JointLimits(limits.names, limits.lower, limits.upper, limits.velocity, accel, limits.effort)
    return ArmSpec(name, urdf, base, joints, kinematics, flange, payload, repeat_mm / 1000.0, speed, tuple(home),
                   _tool_classes(r, robot, table))


def _tool_classes(r: _Reader, robot: dict[str, Any], table: str) -> tuple[str, ...] | None:
    """``tool_classes``: the tool classes the arm is fitted to work with (None: every one)."""
    if "tool_classes" not in robot:
        return None
    value = robot["tool_classes"]
    known = [c.value for c in Tool]
    if not isinstance(value, list) or not value or not all(isinstance(v, str) and v in known for v in value):
        r.fail(f"{table}.tool_classes", f"must be a non-empty list of tool classes ({', '.join(known)}), got {value!r}")
        return None
    return tuple(value)


def _read_urdf(r: _Reader, urdf: Path, flange: str) -> tuple[JointLimits, ArmKinematics] | None:
    """Joint limits and kinematic parameters of the arm's URDF, or None after recording why."""
    try:
        root = ET.parse(urdf).getroot()
    except (OSError, ET.ParseError) as exc:
        r.fail("robot.urdf", f"cannot read URDF {urdf}: {exc}")
        return None
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {link.get("name") for link in root.findall("link")}
    if flange and flange not in links:
        r.fail("link", f"flange link {flange!r} not in the URDF", urdf)
    lower, upper, velocity, effort, origins = [], [], [], [], {}
    for name in ARM_JOINTS:
        joint = joints.get(name)
        if joint is None:
            r.fail(f"joint {name}", "missing", urdf)
            return None
        if joint.get("type") != "revolute":
            r.fail(f"joint {name}.type", f"must be revolute, got {joint.get('type')!r}", urdf)
        axis = _floats(joint.find("axis"), "xyz", "1 0 0")
        if axis is None or not np.allclose(axis, _JOINT_AXES[name], atol=_TOL):
            r.fail(f"joint {name}.axis", f"must be {_JOINT_AXES[name]} (see ArmKinematics)", urdf)
        xyz = _floats(joint.find("origin"), "xyz", "0 0 0")
        rpy = _floats(joint.find("origin"), "rpy", "0 0 0")
        if xyz is None or rpy is None or not np.allclose(rpy, 0.0, atol=_TOL):
            r.fail(f"joint {name}.origin", "needs numeric xyz and zero rpy", urdf)
            xyz = np.zeros(3)
        origins[name] = xyz
        limit = joint.find("limit")
        values = {}
        for key in ("lower", "upper", "velocity", "effort"):
            raw = limit.get(key) if limit is not None else None
            try:
                values[key] = float(raw) if raw is not None else math.nan
            except ValueError:
                values[key] = math.nan
            if not math.isfinite(values[key]):
                r.fail(f"joint {name}.limit.{key}", f"missing or not a number ({raw!r})", urdf)
        if values["lower"] >= values["upper"]:
            r.fail(f"joint {name}.limit", f"lower {values['lower']} must be < upper {values['upper']}", urdf)
        if values["velocity"] <= 0 or values["effort"] <= 0:
            r.fail(f"joint {name}.limit", "velocity and effort must be > 0", urdf)
        lower.append(values["lower"])
        upper.append(values["upper"])
        velocity.append(values["velocity"])
        effort.append(values["effort"])
    kin = _kinematics(r, urdf, origins, joints.get("flange_joint"))
    limits = JointLimits(ARM_JOINTS, tuple(lower), tuple(upper), tuple(velocity), (), tuple(effort))
    return limits, kin


def _kinematics(r: _Reader, urdf: Path, o: dict[str, np.ndarray], flange_joint: ET.Element | None) -> ArmKinematics:
    """Kinematic parameters from the joint origins; records a problem where the structure differs."""
    expect_zero = {"j1": (0, 1), "j2": (1,), "j3": (0, 1), "j4": (1, 2), "j5": (1, 2), "j6": (1, 2)}
    for name, idx in expect_zero.items():
        if not np.allclose(o[name][list(idx)], 0.0, atol=_TOL):
            r.fail(f"joint {name}.origin", f"components {idx} of xyz must be 0 for the spherical-wrist structure", urdf)
    d6_tail = 0.0
    xyz = _floats(flange_joint.find("origin"), "xyz", "0 0 0") if flange_joint is not None else None
    rpy = _floats(flange_joint.find("origin"), "rpy", "0 0 0") if flange_joint is not None else None
    if xyz is None or rpy is None or not np.allclose(xyz[1:], 0.0, atol=_TOL) or not np.allclose(
        frames.rpy_to_matrix(rpy)[:, 2], (1.0, 0.0, 0.0), atol=1e-6
    ):
        r.fail("joint flange_joint", "must exist, lie on j6's axis and turn z onto it (rpy 0 pi/2 0)", urdf)
    else:
        d6_tail = float(xyz[0])
    return ArmKinematics(
        d1=float(o["j1"][2] + o["j2"][2]),
        a1=float(o["j2"][0]),
        a2=float(o["j3"][2]),
        d4=float(o["j4"][0] + o["j5"][0]),
        d6=float(o["j6"][0] + d6_tail),
    )


def _floats(element: ET.Element | None, attr: str, default: str) -> np.ndarray | None:
    text = element.get(attr, default) if element is not None else default
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        return None
    return values if values.shape == (3,) else None


def _read_part(r: _Reader, part: dict[str, Any]) -> PartPlacement:
    scale = r.number(part, "scale", "part.scale", low=0.0, strict_low=True)
    x_axis = r.vec3(part, "x_axis", "part.x_axis")
    y_axis = r.vec3(part, "y_axis", "part.y_axis")
    try:
        rot = frames.axes_to_matrix(x_axis, y_axis)
    except ValueError as exc:
        r.fail("part.x_axis", f"x_axis and y_axis: {exc}")
        rot = np.eye(3)
    translation = r.vec3(part, "translation", "part.translation")
    if "envelope_min_mm" not in part and "envelope_max_mm" not in part:
        lo, hi = (-math.inf,) * 3, (math.inf,) * 3     # from the part's mesh (workcell_for)
    else:
        lo = r.vec3(part, "envelope_min_mm", "part.envelope_min_mm")
        hi = r.vec3(part, "envelope_max_mm", "part.envelope_max_mm")
    if any(a >= b for a, b in zip(lo, hi)):
        r.fail("part.envelope_max_mm", "must exceed envelope_min_mm on every axis")
    r0, r1, r2 = ((float(a), float(b), float(c)) for a, b, c in rot)
    return PartPlacement(scale, (r0, r1, r2), translation, lo, hi)


def _read_tools(r: _Reader, data: dict[str, Any], payload: float) -> tuple[ToolSpec, ...]:
    tools = []
    for i, t in enumerate(r.tables(data, "tool", "tool")):
        name = t.get("name") if isinstance(t.get("name"), str) else str(i)
        f = f"tool[{name}]"
        name = r.text(t, "name", f"{f}.name")
        cls_text = r.text(t, "class", f"{f}.class")
        try:
            tool_class = Tool(cls_text)
        except ValueError:
            r.fail(f"{f}.class", f"must be one of {[c.value for c in Tool]}, got {cls_text!r}")
            tool_class = Tool.ULTRASONIC
        weight = r.number(t, "weight_kg", f"{f}.weight_kg", low=0.0, strict_low=True)
        if payload and weight > payload:
            r.fail(f"{f}.weight_kg", f"{weight:g} kg exceeds the arm's payload {payload:g} kg")
        tcp = r.pose(t, f, position_key="tcp_position", rpy_key="tcp_rpy_deg")
        if tcp.position[2] <= 0:
            r.fail(f"{f}.tcp_position", "the tool point must lie beyond the flange (z > 0)")
        body_center = r.vec3(t, "body_center", f"{f}.body_center")
        body = r.vec3(t, "body_size", f"{f}.body_size", positive=True)
        standoff = r.vec3(t, "standoff", f"{f}.standoff", nonnegative=True)
        if not standoff[0] <= standoff[1] <= standoff[2]:
            r.fail(f"{f}.standoff", f"must be [min, nominal, max] in order, got {list(standoff)}")
        if tool_class is Tool.SLRA and standoff[2] <= 0:
            r.fail(f"{f}.standoff", "an SLRA needs a standoff range > 0")
        approach = r.number(t, "approach_distance", f"{f}.approach_distance", low=0.0)
        fov = r.vec2(t, "fov_deg", f"{f}.fov_deg", nonnegative=True)
        if any(v >= 180 for v in fov):
            r.fail(f"{f}.fov_deg", "must be < 180 degrees")
        holder = r.number(t, "holder_radius", f"{f}.holder_radius", low=0.0, strict_low=True,
                          default=PROBE_HOLDER_RADIUS)
        shaft = r.number(t, "shaft_radius", f"{f}.shaft_radius", low=0.0, strict_low=True,
                         default=PROBE_SHAFT_RADIUS)
        tools.append(ToolSpec(name, tool_class, weight, tcp, body_center, body, standoff[0], standoff[1], standoff[2],
                              approach, fov, holder, shaft))
    if not tools:
        r.fail("tool", "at least one [[tool]] is needed")
    return tuple(tools)


def _read_rack(r: _Reader, rack: dict[str, Any], tool_names: set[str]) -> Rack:
    name = r.text(rack, "name", "rack.name")
    box = r.box(rack, "rack", name or "rack")
    slots, held = [], set()
    for i, s in enumerate(r.tables(rack, "slot", "rack.slot")):
        label = s.get("name") if isinstance(s.get("name"), str) else str(i)
        f = f"rack.slot[{label}]"
        slot_name = r.text(s, "name", f"{f}.name")
        pose = r.pose(s, f, position_key="position")
        tool = s.get("tool", "")
        if not isinstance(tool, str):
            r.fail(f"{f}.tool", "must be a tool name or empty")
            tool = ""
        if tool and tool not in tool_names:
            r.fail(f"{f}.tool", f"no [[tool]] named {tool!r}")
        if tool and tool in held:
            r.fail(f"{f}.tool", f"tool {tool!r} is in two slots")
        held.add(tool)
        slots.append(RackSlot(slot_name, pose, tool))
    if not slots:
        r.fail("rack.slot", "the rack needs at least one [[rack.slot]]")
    approach = r.number(rack, "approach_m", "rack.approach_m", low=0.0, strict_low=True, high=1.0,
                        default=RACK_APPROACH_M)
    return Rack(name, box, tuple(slots), approach)


def _read_reach(r: _Reader, data: dict[str, Any]) -> ReachParams:
    low_z = r.number(data, "wrist_min_height", "reach.wrist_min_height")
    high_z = r.number(data, "wrist_max_height", "reach.wrist_max_height")
    if high_z <= low_z:
        r.fail("reach.wrist_max_height", "must exceed reach.wrist_min_height")
    counts = {}
    for key in ("standoff_samples", "roll_samples"):
        value = data.get(key)
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            r.fail(f"reach.{key}", "missing" if value is None else f"must be an integer >= 1, got {value!r}")
            value = 1
        counts[key] = value
    return ReachParams(
        margin=r.number(data, "margin", "reach.margin", low=0.0, strict_low=True, high=1.0),
        base_keepout_radius=r.number(data, "base_keepout_radius", "reach.base_keepout_radius", low=0.0),
        wrist_min_height=low_z,
        wrist_max_height=high_z,
        tcp_min_height=r.number(data, "tcp_min_height", "reach.tcp_min_height"),
        part_clearance=r.number(data, "part_clearance", "reach.part_clearance", low=0.0),
        standoff_samples=counts["standoff_samples"],
        roll_samples=counts["roll_samples"],
    )


def _check_unique_names(r: _Reader, cell: Workcell) -> None:
    seen: set[str] = set()
    names = [b.name for b in cell.static_boxes()] + [t.name for t in cell.tools] + [s.name for s in cell.rack.slots]
    for name in names:
        if name in seen:
            r.fail(name, f"name {name!r} is used twice")
        seen.add(name)


def workcell_for(part_directory: Path | str | None, bounds: Any = None) -> Workcell:
    """The workcell of a part: its directory's own ``workcell.toml`` when it has one, else
    the built-in workcell (also for None, the built-in part).

    bounds: the part mesh's box (2, 3) mm.  The part's envelope (the box the wrist and the
    SLRA stay out of) is the one its own workcell.toml states, else this box: a user part
    in the built-in cell never keeps the built-in bulkhead's envelope.
    """
    own = None if part_directory is None else Path(part_directory) / "workcell.toml"
    has_own = own is not None and own.is_file()
    cell = load_workcell(own if has_own else None)
    stated = has_own and all(map(math.isfinite, cell.part.envelope_min_mm))
    if bounds is None or stated or (not has_own and _is_builtin(part_directory)):
        if not all(map(math.isfinite, cell.part.envelope_min_mm)):
            raise InputError([(Location(str(own)), "[part] has no envelope_min_mm/envelope_max_mm and no part mesh "
                                                   "was given to take them from")])
        return cell
    lo, hi = np.asarray(bounds, dtype=float)
    placement = replace(cell.part, envelope_min_mm=(float(lo[0]), float(lo[1]), float(lo[2])),
                        envelope_max_mm=(float(hi[0]), float(hi[1]), float(hi[2])))
    return replace(cell, part=placement)


def _is_builtin(part_directory: Path | str | None) -> bool:
    if part_directory is None:
        return True
    try:
        return Path(part_directory).resolve() == builtin_dir().resolve()
    except OSError:
        return False
