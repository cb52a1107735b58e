"""Parts the code was not written around, made as a user would: a mesh, a specs.csv and
(optionally) a workcell.toml, and nothing else (no features.json, no truth).

- `make_plate(dir)`: a 400 x 300 mm pocketed plate: two pockets on a 3 mm web, a 4 mm rib
  between them, holes through the web (+Z), blind holes in a wall's top with their edge
  distances, and holes through the side wall (+X): holes in two directions.
- `make_scaled_mesh_part(dir)`: a mesh from an installed package (pybullet's shape-sorter
  box, in metres), scaled to millimetres, with the specs a user would write on it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import trimesh

from ita.paths import resource_dir
from ita.specs.io import COLUMNS

HEADER = ",".join(COLUMNS)


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))


def _cylinder(centre, axis, radius, length) -> trimesh.Trimesh:
    """A cylinder of `length` centred on `centre` along unit `axis` (a cutter)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.asarray(axis, float)
    rot = trimesh.geometry.align_vectors(z, axis)
    rot[:3, 3] = centre
    return trimesh.creation.cylinder(radius=radius, height=length, sections=128, transform=rot)


def _row(sid, kind, feature, p, n, nominal, lower, upper, datum="A", d=None, note=""):
    d = d or ("", "", "")
    return ",".join(str(x) for x in (sid, kind, feature, *p, *n, nominal, lower, upper, datum, *d, note))


PLATE_WEB = 3.0
PLATE_TOP = 30.0


def plate_mesh() -> trimesh.Trimesh:
    """The pocketed plate, mm, datum A (its back face) at z = 0, the pockets open to +Z."""
    solid = _box((-200, -150, 0), (200, 150, PLATE_TOP))
    cutters = [_box((-190, -140, PLATE_WEB), (-2, 140, PLATE_TOP + 5)), _box((2, -140, PLATE_WEB), (190, 140, PLATE_TOP + 5))]
    for x, y in ((-120, -60), (-80, 70), (90, -50), (130, 60)):               # 8 mm through the web
        cutters.append(_cylinder((x, y, 0), (0, 0, 1), 4.0, 20.0))
    for x in (-100.0, 100.0):                                                  # 4 mm blind in the wall top, 12 deep
        cutters.append(_cylinder((x, -145, PLATE_TOP), (0, 0, 1), 2.0, 24.0))
    for y in (-60.0, 60.0):                                                    # 6 mm through the +X side wall
        cutters.append(_cylinder((200, y, 15), (1, 0, 0), 3.0, 30.0))
    return solid.difference(trimesh.boolean.union(cutters))


def plate_specs() -> list[str]:
    rows = []
    for i, (x, y) in enumerate(((-150, 0), (-40, 100), (60, -100), (150, 0))):
        rows.append(_row(f"WT-{i + 1}", "web_thickness", f"P{i // 2 + 1}", (x, y, PLATE_WEB), (0, 0, 1), PLATE_WEB,
                         -0.127, 0.127, note="pocket floor"))
    for i, y in enumerate((-80.0, 80.0)):
        rows.append(_row(f"SH-R1-{i + 1}", "stiffener_height", "R1", (0, y, PLATE_TOP), (0, 0, 1), PLATE_TOP,
                         -0.25, 0.25, note="rib top above datum A"))
        rows.append(_row(f"SW-R1-{i + 1}", "stiffener_width", "R1", (0, y, PLATE_TOP), (0, 0, 1), 4.0,
                         -0.127, 0.127, d=(1, 0, 0), note="rib thickness"))
    for i, (x, y) in enumerate(((-120, -60), (-80, 70), (90, -50), (130, 60))):
        rows.append(_row(f"HD-W{i + 1}", "hole_diameter", f"W{i + 1}", (x, y, PLATE_WEB), (0, 0, 1), 8.0, -0.076,
                         0.076, note="hole through the web"))
        rows.append(_row(f"HP-W{i + 1}", "hole_position", f"W{i + 1}", (x, y, PLATE_WEB), (0, 0, 1), 0.0, 0.0, 0.5,
                         note="true position"))
    for i, x in enumerate((-100.0, 100.0)):
        rows.append(_row(f"HD-T{i + 1}", "hole_diameter", f"T{i + 1}", (x, -145, PLATE_TOP), (0, 0, 1), 4.0,
                         -0.076, 0.076, note="blind hole in the wall top"))
        rows.append(_row(f"ED-T{i + 1}", "edge_distance", f"T{i + 1}", (x, -147.5, PLATE_TOP), (0, 0, 1), 5.0,
                         -0.5, 0.5, d=(0, -1, 0), note="hole centre to the wall's outer edge"))
    for i, y in enumerate((-60.0, 60.0)):
        rows.append(_row(f"HD-S{i + 1}", "hole_diameter", f"S{i + 1}", (200, y, 15), (1, 0, 0), 6.0, -0.076, 0.076,
                         note="hole through the side wall along +X"))
        rows.append(_row(f"HP-S{i + 1}", "hole_position", f"S{i + 1}", (200, y, 15), (1, 0, 0), 0.0, 0.0, 0.5,
                         note="true position along +X"))
    return rows


def own_workcell(translation=(1.75, 0.0, 1.35)) -> str:
    """The built-in workcell.toml with the part placed at `translation`, turned 30 degrees
    about the vertical so that its +X side faces the robot a little (the SLRA sees the side
    holes along their axes from there), and its envelope left to the part's mesh (the URDF
    named where it lies)."""
    text = (resource_dir("bulkhead") / "workcell.toml").read_text()
    urdf = (resource_dir("bulkhead") / "t3_arm.urdf").resolve()
    text = re.sub(r'urdf = "t3_arm.urdf"', f'urdf = "{urdf}"', text)
    text = re.sub(r"translation = \[2\.0, 0\.0, 1\.45\]", f"translation = [{', '.join(map(str, translation))}]", text)
    text = re.sub(r"x_axis = \[0\.0, -1\.0, 0\.0\]", "x_axis = [-0.5, -0.8660254, 0.0]", text)
    text = re.sub(r"envelope_m(in|ax)_mm = .*\n", "", text)
    return text


def make_plate(directory: Path) -> Path:
    """The plate's directory: plate.stl, specs.csv and its own workcell.toml."""
    directory.mkdir(parents=True, exist_ok=True)
    plate_mesh().export(directory / "plate.stl")
    (directory / "specs.csv").write_text("\n".join([HEADER, *plate_specs()]) + "\n")
    (directory / "workcell.toml").write_text(own_workcell())
    return directory


def scaled_package_mesh() -> trimesh.Trimesh:
    """pybullet's shape-sorter box (pybullet_data/toys/shape_sorter.obj, installed with
    pybullet; metres), scaled to millimetres: an open box 400 mm a side with 20 mm walls,
    turned so its opening faces +Z (the robot) and set on z = 0, centred in XY."""
    import pybullet_data

    mesh = trimesh.load(Path(pybullet_data.getDataPath()) / "toys" / "shape_sorter.obj", force="mesh")
    mesh.apply_scale(1000.0)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1.0, 0.0, 0.0]))
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return mesh


def box_specs(mesh: trimesh.Trimesh) -> list[str]:
    """What a user would spec on the box, nominals read off its mesh: each wall's thickness at
    its top (the laser, across the wall), two walls' height above the bottom (datum A), and
    the floor's thickness from inside (the gauge; 385 mm down a 360 mm opening, out of reach)."""
    lo, hi = mesh.bounds
    top = float(hi[2])
    rows = []
    for k, (point, across) in enumerate((((0.0, float(lo[1]) + 10.0), (0.0, 1.0)),
                                          ((0.0, float(hi[1]) - 10.0), (0.0, -1.0)),
                                          ((float(lo[0]) + 10.0, 0.0), (1.0, 0.0)),
                                          ((float(hi[0]) - 10.0, 0.0), (-1.0, 0.0)))):
        o = np.array([[point[0], point[1], top - 0.3]] * 2)
        d = np.array([[across[0], across[1], 0.0], [-across[0], -across[1], 0.0]])
        locations, index, _ = mesh.ray.intersects_location(o, d, multiple_hits=False)
        width = float(sum(np.linalg.norm(locations[index == i] - o[i], axis=1).min() for i in (0, 1)))
        p = (point[0], point[1], top)
        rows.append(_row(f"SW-W{k + 1}", "stiffener_width", f"W{k + 1}", p, (0, 0, 1), round(width, 3), -0.2, 0.2,
                         d=(across[0], across[1], 0), note="wall thickness at its top"))
        if k < 2:
            rows.append(_row(f"SH-W{k + 1}", "stiffener_height", f"W{k + 1}", p, (0, 0, 1), round(top, 3), -0.5, 0.5,
                             note="wall top above the bottom"))
    locations, _, _ = mesh.ray.intersects_location([[0.0, 0.0, top + 10]], [[0.0, 0.0, -1.0]], multiple_hits=False)
    floor = float(locations[0, 2])
    rows.append(_row("WT-F1", "web_thickness", "F1", (0.0, 0.0, round(floor, 4)), (0, 0, 1), round(floor - float(lo[2]), 3),
                     -0.2, 0.2, note="floor thickness from inside"))
    return rows


def make_scaled_mesh_part(directory: Path) -> Path:
    """A part of a mesh from an installed package (see :func:`scaled_package_mesh`) with the
    specs of :func:`box_specs` and the plate's cell."""
    directory.mkdir(parents=True, exist_ok=True)
    mesh = scaled_package_mesh()
    mesh.export(directory / "box.stl")
    (directory / "specs.csv").write_text("\n".join([HEADER, *box_specs(mesh)]) + "\n")
    (directory / "workcell.toml").write_text(own_workcell())
    return directory


RIM_WEB = 3.0
RIM_TOP = 30.0
RIM_WALL = 12.0
RIM_X, RIM_Y = 250.0, 200.0           # the plate's half size


def rim_plate_mesh() -> trimesh.Trimesh:
    """A 500 x 400 mm plate whose rim is a wall 12 mm thick and 30 mm high (no flange cap),
    a 3 mm web in two pockets parted by a 4 mm rib, a lightening hole in each pocket; datum A
    (the back face) at z = 0."""
    x0, y0, w = RIM_X - RIM_WALL, RIM_Y - RIM_WALL, 2.0
    solid = _box((-RIM_X, -RIM_Y, 0), (RIM_X, RIM_Y, RIM_TOP))
    cutters = [_box((-x0, -y0, RIM_WEB), (-w, y0, RIM_TOP + 5)), _box((w, -y0, RIM_WEB), (x0, y0, RIM_TOP + 5))]
    for x in (-120.0, 120.0):
        cutters.append(_cylinder((x, 0, 0), (0, 0, 1), 20.0, 20.0))
    return solid.difference(trimesh.boolean.union(cutters))


def rim_plate_specs() -> list[str]:
    """Web thicknesses, the rim's heights (no width spec: a wall has no cap) and its wall
    thicknesses from outside, the rib's heights and widths, the lightening holes."""
    rows = []
    for i, (x, y) in enumerate(((-180, 100), (-60, -120), (60, 120), (180, -100))):
        rows.append(_row(f"WT-{i + 1}", "web_thickness", f"P{i // 2 + 1}", (x, y, RIM_WEB), (0, 0, 1), RIM_WEB,
                         -0.127, 0.127, note="pocket floor"))
    mid = RIM_WALL / 2
    sides = [("N", (0.0, 1.0), ((-120.0, RIM_Y), (120.0, RIM_Y))), ("S", (0.0, -1.0), ((-120.0, -RIM_Y), (120.0, -RIM_Y))),
             ("E", (1.0, 0.0), ((RIM_X, -100.0), (RIM_X, 100.0))), ("W", (-1.0, 0.0), ((-RIM_X, -100.0), (-RIM_X, 100.0)))]
    for side, (nx, ny), points in sides:
        for k, (x, y) in enumerate(points):
            top = (x - nx * mid, y - ny * mid, RIM_TOP)
            rows.append(_row(f"FH-{side}{k + 1}", "flange_height", f"RIM-{side}", top, (0, 0, 1), RIM_TOP, -0.25, 0.25,
                             note="rim wall's top above datum A"))
            rows.append(_row(f"FT-{side}{k + 1}", "flange_thickness", f"RIM-{side}", (x, y, RIM_TOP / 2), (nx, ny, 0),
                             RIM_WALL, -0.127, 0.127, note="rim wall from its outer face"))
    for i, y in enumerate((-100.0, 100.0)):
        rows.append(_row(f"SH-R1-{i + 1}", "stiffener_height", "R1", (0, y, RIM_TOP), (0, 0, 1), RIM_TOP,
                         -0.25, 0.25, note="rib top above datum A"))
        rows.append(_row(f"SW-R1-{i + 1}", "stiffener_width", "R1", (0, y, RIM_TOP), (0, 0, 1), 4.0,
                         -0.127, 0.127, d=(1, 0, 0), note="rib thickness"))
    for i, x in enumerate((-120.0, 120.0)):
        rows.append(_row(f"HD-L{i + 1}", "hole_diameter", f"L{i + 1}", (x, 0, RIM_WEB), (0, 0, 1), 40.0, -0.1, 0.1,
                         note="lightening hole"))
        rows.append(_row(f"HP-L{i + 1}", "hole_position", f"L{i + 1}", (x, 0, RIM_WEB), (0, 0, 1), 0.0, 0.0, 0.5,
                         note="true position"))
    return rows


def make_rim_plate(directory: Path) -> Path:
    """The rim-walled plate's directory: plate.stl, specs.csv and its own workcell.toml."""
    directory.mkdir(parents=True, exist_ok=True)
    rim_plate_mesh().export(directory / "plate.stl")
    (directory / "specs.csv").write_text("\n".join([HEADER, *rim_plate_specs()]) + "\n")
    (directory / "workcell.toml").write_text(own_workcell())
    return directory
