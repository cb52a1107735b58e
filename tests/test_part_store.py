"""Loading parts: the built-in bulkhead materialised once, user directories checked."""

from __future__ import annotations

import json
import multiprocessing
import shutil

import numpy as np
import pytest

from ita.errors import InputError
from ita.part import store
from ita.part.model import Hole, Stiffener
from ita.specs.io import read_specs


def test_builtin_is_materialised_with_its_files(builtin_part, ita_home):
    d = builtin_part.directory
    assert d == ita_home / "parts" / "bulkhead"
    for name in ("part.json", "nominal.stl", "specs.csv", "features.json", "truth"):
        assert (d / name).exists(), name
    meta = json.loads((d / "part.json").read_text())
    assert meta["fingerprint"] and meta["specs_sha256"]
    assert builtin_part.mesh.is_watertight
    assert len(read_specs(builtin_part.specs_path)) >= 900
    assert len(builtin_part.features) > 200


def test_second_load_reuses_the_materialised_part(builtin_part):
    before = (builtin_part.directory / "part.json").stat().st_mtime_ns
    again = store.load_part(None)
    assert (again.directory / "part.json").stat().st_mtime_ns == before


def _stale(home):
    meta_path = home / "parts" / "bulkhead" / "part.json"
    meta = json.loads(meta_path.read_text())
    meta["fingerprint"] = "old"
    meta_path.write_text(json.dumps(meta))


def test_stale_part_is_regenerated_but_edited_specs_are_kept(tmp_path, monkeypatch, builtin_part):
    monkeypatch.setenv("ITA_HOME", str(tmp_path))
    shutil.copytree(builtin_part.directory, tmp_path / "parts" / "bulkhead")
    specs = tmp_path / "parts" / "bulkhead" / "specs.csv"
    edited = specs.read_text().replace("pocket floor, ultrasonic", "pocket floor, edited", 1)
    specs.write_text(edited)
    _stale(tmp_path)
    with pytest.warns(store.PartWarning, match="edited"):
        part = store.load_part(None)
    assert part.specs_path.read_text() == edited
    assert (part.directory / "specs.generated.csv").is_file()
    meta = json.loads((part.directory / "part.json").read_text())
    assert meta["fingerprint"] != "old" and meta["specs_edited"]


def test_stale_unedited_part_is_regenerated_silently(tmp_path, monkeypatch, builtin_part, recwarn):
    monkeypatch.setenv("ITA_HOME", str(tmp_path))
    shutil.copytree(builtin_part.directory, tmp_path / "parts" / "bulkhead")
    _stale(tmp_path)
    part = store.load_part(None)
    assert not [w for w in recwarn if issubclass(w.category, store.PartWarning)]
    assert not (part.directory / "specs.generated.csv").exists()
    assert not [p for p in (tmp_path / "parts").iterdir() if p.name.startswith(".bulkhead-")]


def _load_in_child(home: str) -> str:
    import os

    os.environ["ITA_HOME"] = home
    return str(store.load_part(None).directory)


@pytest.mark.slow
def test_two_processes_racing_materialise_once(tmp_path):
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(2) as pool:
        dirs = pool.map(_load_in_child, [str(tmp_path)] * 2)
    assert dirs[0] == dirs[1]
    assert [p.name for p in (tmp_path / "parts").iterdir() if not p.name.startswith(".bulkhead.lock")] == ["bulkhead"]


def test_build_copies_an_editable_part(tmp_path, builtin_part):
    out = store.build_part(tmp_path / "mine")
    part = store.load_part(out)
    assert part.mesh.is_watertight and part.features
    assert (out / "truth").is_dir()
    with pytest.raises(InputError, match="not an empty directory"):
        store.build_part(out)


def test_user_part_with_obj_mesh(tmp_path, builtin_part):
    d = tmp_path / "p"
    d.mkdir()
    builtin_part.mesh.export(d / "thing.obj")
    shutil.copy(builtin_part.specs_path, d / "specs.csv")
    part = store.load_part(d)
    assert part.name == "p" and part.unfound == ()
    assert len(part.mesh.faces) == len(builtin_part.mesh.faces)
    # without features.json, every feature the SLRA's specs name is found on the mesh, as generated
    generated = {f.id: f for f in builtin_part.features}
    assert set(part.found) == {f.id for f in part.features} and len(part.found) > 200
    for f in part.features:
        g = generated[f.id]
        assert type(f) is type(g)
        if isinstance(f, Hole):
            assert np.allclose(f.center, g.center, atol=1e-3) and f.diameter == g.diameter
            assert f.depth == pytest.approx(g.depth, abs=1e-3)
        elif isinstance(f, Stiffener):
            assert (f.width, f.height) == pytest.approx((g.width, g.height), abs=1e-3)
        else:
            assert (f.cap_width, f.wall_thickness, f.cap_thickness, f.height) == pytest.approx(
                (g.cap_width, g.wall_thickness, g.cap_thickness, g.height), abs=3e-3)


@pytest.mark.parametrize("files, message", [
    ((), "no mesh"),
    (("a.stl", "b.ply"), "2 meshes"),
    (("a.stl",), "no specs.csv"),
])
def test_user_part_errors_name_dir_and_what_is_missing(tmp_path, files, message):
    for name in files:
        (tmp_path / name).write_text("solid x\nendsolid x\n")
    with pytest.raises(InputError) as info:
        store.load_part(tmp_path)
    assert message in str(info.value) and str(tmp_path) in str(info.value)


def test_missing_dir_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="not found"):
        store.load_part(tmp_path / "nope")


def _plate_part(d, scale: float, spec_scale: float = 1.0):
    """A 800 x 500 x 10 mm plate (its mesh scaled by `scale`) with three web specs on its top
    face (their points scaled by `spec_scale`)."""
    import trimesh

    d.mkdir()
    trimesh.creation.box((800.0, 500.0, 10.0)).apply_translation((0, 0, 5.0)).apply_scale(scale).export(d / "p.stl")
    rows = ["id,kind,feature,x,y,z,nx,ny,nz,nominal,lower,upper,datum,dx,dy,dz,note"]
    for i, (x, y) in enumerate([(-300.0, -200.0), (0.0, 0.0), (300.0, 200.0)]):
        rows.append(f"WT-{i},web_thickness,plate,{x * spec_scale},{y * spec_scale},{10.0 * spec_scale},0,0,1,10,"
                    f"-0.1,0.1,A,,,,")
    (d / "specs.csv").write_text("\n".join(rows) + "\n")
    return d


def test_a_mesh_in_metres_is_refused_saying_so(tmp_path):
    from click.testing import CliRunner

    from ita.cli import main

    d = _plate_part(tmp_path / "metres", 0.001)
    result = CliRunner().invoke(main, ["part", "info", "--part", str(d)])
    assert result.exit_code == 2 and "in metres?" in result.output and "p.stl" in result.output


def test_specs_and_mesh_in_different_units_are_named(tmp_path):
    from click.testing import CliRunner

    from ita.cli import main

    d = _plate_part(tmp_path / "inches", 1 / 25.4)
    result = CliRunner().invoke(main, ["spec", "validate", "--part", str(d)])
    assert result.exit_code == 2 and "mesh in inches?" in result.output
    ok = _plate_part(tmp_path / "mm", 1.0)
    assert CliRunner().invoke(main, ["spec", "validate", "--part", str(ok)]).exit_code == 0
