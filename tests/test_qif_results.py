"""`ita results RUN --qif FILE`: a run as one QIF 3.0 results document, valid against the
official schema (../shared/qif/schema/), every result with its status and uncertainty,
the inspection status the part's verdict; and ITA's own export read back as the same
specs (`ita spec import FILE.qif --out DIR`)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.archive import Archive, Outcome, Result, RunStatus, archive_path
from ita.cli import main
from ita.report.data import collect, summarize
from ita.specs.io import read_specs, write_specs
from ita.specs.model import MeasurementKind

etree = pytest.importorskip("lxml.etree")

REPO = Path(__file__).resolve().parent.parent
SCHEMA = REPO.parent / "shared" / "qif" / "schema" / "QIFApplications" / "QIFDocument.xsd"
NS = {"q": "http://qifstandards.org/xsd/qif3"}
STATUS = {"conforms": "PASS", "does_not_conform": "FAIL", "uncertain": "INDETERMINATE",
          "not_done": "NOT_ANALYZED", "cannot_be_done": "NOT_ANALYZED"}
TYPES = {"web_thickness": "Thickness", "flange_thickness": "Thickness", "hole_diameter": "Diameter",
         "hole_position": "Position", "edge_distance": "DistanceBetween", "flange_height": "Height",
         "stiffener_height": "Height", "flange_width": "Width", "stiffener_width": "Width"}


def run(*args: str):
    return CliRunner().invoke(main, list(args))


@pytest.fixture(scope="module")
def schema():
    """The official QIF 3.0 schema (lxml), from the shared folder beside the checkout."""
    if not SCHEMA.is_file():
        pytest.skip(f"the QIF 3.0 schema is not at {SCHEMA} (the shared folder ../shared/qif/ is absent)")
    return etree.XMLSchema(etree.parse(str(SCHEMA)))


def valid(schema, path: Path):
    """The parsed document, asserting it validates (the schema's first errors shown)."""
    doc = etree.parse(str(path))
    ok = schema.validate(doc)
    assert ok, "\n".join(f"line {e.line}: {e.message}" for e in list(schema.error_log)[:10])
    return doc


def measurements(doc) -> dict[str, list]:
    """Spec id -> its characteristic measurements (through the item they name)."""
    items = {i.get("id"): i.findtext("q:Name", namespaces=NS)
             for i in doc.xpath("//q:CharacteristicItems/*", namespaces=NS)}
    out: dict[str, list] = {}
    for m in doc.xpath("//q:CharacteristicMeasurements/*", namespaces=NS):
        out.setdefault(items[m.findtext("q:CharacteristicItemId", namespaces=NS)], []).append(m)
    return out


def check_against_archive(doc, runs: Path) -> None:
    """Every result of the run's archive is one measurement of its spec's item, with its
    status, value and u; the inspection status is the part's verdict."""
    with Archive.open(runs / "archive.sqlite", create=False) as a:
        run_id = a.runs()[-1].id
        info = a.run(run_id)
        specs = read_specs(Path(info.part_dir) / "specs.csv")
        data = collect(a, run_id, specs=specs)
        verdict = summarize(data).verdict
    found = measurements(doc)
    assert sorted(found) == sorted(r.spec_id for r in data.results)
    for r in data.results:
        (m,) = found[r.spec_id]
        status = r.decision.value if r.decision is not None else r.outcome.value
        assert m.findtext("q:Status/q:CharacteristicStatusEnum", namespaces=NS) == STATUS[status]
        assert etree.QName(m).localname == f"{TYPES[r.kind]}CharacteristicMeasurement"
        value = m.find("q:Value", namespaces=NS)
        if r.value is None:
            assert value is None and m.findtext("q:Description", namespaces=NS)
        else:
            assert float(value.text) == r.value and float(value.get("combinedUncertainty")) == r.u
    inspection = doc.xpath("//q:MeasurementResults/q:InspectionStatus/q:InspectionStatusEnum/text()",
                           namespaces=NS)
    assert inspection == [{"accept": "PASS", "reject": "FAIL", "incomplete": "UNKNOWN"}[verdict.value]]
    assert doc.xpath("//q:InspectionTraceability/q:ReportNumber/text()", namespaces=NS) == [run_id]


# --------------------------------------------------------------------- real short runs
@pytest.fixture(scope="module")
def short_run(tmp_path_factory, builtin_part) -> Path:
    runs = tmp_path_factory.mktemp("runs")
    res = run("inspect", "--limit", "4", "--runs-dir", str(runs))
    assert res.exit_code == 0, res.output
    return runs


@pytest.fixture(scope="module")
def fault_run(tmp_path_factory, builtin_part) -> Path:
    """Faults at a rate of 0.3 over twelve measurements and the arm drifting from the start
    (the cell's interim check finds it; the Exception Handler puts every fault right)."""
    runs = tmp_path_factory.mktemp("runs")
    res = run("inspect", "--limit", "12", "--faults", "0.3", "--seed", "1", "--alarm-after", "0",
              "--inject", "position_drift:after=0", "--runs-dir", str(runs))
    assert res.exit_code in (0, 3), res.output
    return runs


def test_a_short_run_writes_a_valid_qif_with_every_result(short_run: Path, schema, tmp_path: Path) -> None:
    out = tmp_path / "run.qif"
    res = run("results", "last", "--runs-dir", str(short_run), "--qif", str(out))
    assert res.exit_code == 0, res.output
    assert "QIF 3.0 results of run" in res.stdout and "inspection status UNKNOWN" in res.stdout
    doc = valid(schema, out)
    check_against_archive(doc, short_run)
    devices = doc.xpath("//q:MeasurementDevices/q:MeasurementDevice/q:Name/text()", namespaces=NS)
    assert devices and all(d.startswith(("us_probe", "slra")) for d in devices)
    version = doc.xpath("//q:InspectionProgram/q:File/q:Version/text()", namespaces=NS)[0]
    assert version.startswith("ita ") and "digest" in version     # program revision: version and plan
    # the part's registration on its datums: an actual transform, and its line for people
    name = doc.xpath("//q:ActualTransforms/q:Transform/q:Name/text()", namespaces=NS)
    assert name and "TH-B" in name[0] and "TH-C" in name[0]
    origin = [float(x) for x in doc.xpath("//q:ActualTransforms/q:Transform/q:Origin/text()", namespaces=NS)[0].split()]
    assert len(origin) == 3 and max(abs(x) for x in origin) < 2.0     # the fixture's error: tenths of a mm
    line = doc.xpath("//q:Attributes/q:AttributeStr[@name='ita.alignment']/@value", namespaces=NS)
    assert line and "residuals" in line[0]


def test_a_run_with_faults_exports_every_result_the_handler_recovered(fault_run: Path, schema,
                                                                      tmp_path: Path) -> None:
    out = tmp_path / "faults.qif"
    res = run("results", "last", "--runs-dir", str(fault_run), "--qif", str(out))
    assert res.exit_code == 0, res.output
    doc = valid(schema, out)
    check_against_archive(doc, fault_run)
    statuses = doc.xpath("//q:CharacteristicMeasurements/*/q:Status/q:CharacteristicStatusEnum/text()",
                         namespaces=NS)
    with Archive.open(archive_path(fault_run), create=False) as archive:
        run_id = archive.runs()[-1].id
        causes = [e.payload.get("cause") for e in archive.events(run_id, kinds=["diagnosis"])]
    assert "arm_drift" in causes and len(causes) >= 3, causes
    measured = [s for s in statuses if s in ("PASS", "FAIL", "INDETERMINATE")]
    assert len(statuses) == 12 and len(measured) >= 10, statuses      # faults at 0.3: nearly all recovered


# --------------------------------------------------------------------- every kind and status
def record_kinds_run(archive: Archive, specs, part_dir: Path, settings: dict | None = None,
                     all_conform: bool = False) -> str:
    """A run of `specs` recorded as the Top Level would: values near nominal, and (unless
    `all_conform`) every status: out of tolerance, uncertain, not done, cannot be done."""
    rng = random.Random(7)
    run_id = archive.create_run("bulkhead", part_dir, seed=1, total=len(specs),
                                settings={"simulated": True, "mkb_digest": "ab" * 32, **(settings or {})})
    for i, s in enumerate(specs):
        tool = "us_probe_1" if s.kind.value.endswith("thickness") else "slra_1"
        half = (s.upper - s.lower) / 2
        centre = s.nominal + (s.lower + s.upper) / 2
        if all_conform or i % 6 in (0, 1):
            r = Result.measured(s, centre + rng.uniform(-0.2, 0.2) * half, 0.02 * half, tool=tool)
        elif i % 6 == 2:
            r = Result.measured(s, s.nominal + s.upper + 0.5 * half, 0.02 * half, tool=tool)
        elif i % 6 == 3:
            r = Result.measured(s, s.nominal + s.upper, 0.05 * half, tool=tool)
        elif i % 6 == 4:
            r = Result.unmeasured(s, Outcome.NOT_DONE, "no back-wall echo; diagnosis: dry couplant", tool=tool)
        else:
            r = Result.unmeasured(s, Outcome.CANNOT_BE_DONE, "no tool can reach it")
        archive.record_result(run_id, r)
    archive.set_status(run_id, RunStatus.COMPLETED)
    return run_id


@pytest.fixture(scope="module")
def kinds(builtin_part):
    """Three specs of every kind of the built-in part."""
    specs = read_specs(builtin_part.specs_path)
    return [s for k in MeasurementKind for s in [x for x in specs if x.kind is k][:3]]


def test_every_kind_and_status_validates_with_its_qif_type(builtin_part, kinds, schema, tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as a:
        record_kinds_run(a, kinds, builtin_part.directory, {"serial": "SN-0042", "operator": "A. Lovelace"})
    out = tmp_path / "kinds.qif"
    res = run("results", "last", "--runs-dir", str(runs), "--qif", str(out))
    assert res.exit_code == 0, res.output
    doc = valid(schema, out)
    check_against_archive(doc, runs)
    items = doc.xpath("//q:CharacteristicItems/*", namespaces=NS)
    assert len(items) == len(kinds)
    for item in items:
        spec = next(s for s in kinds if s.id == item.findtext("q:Name", namespaces=NS))
        assert etree.QName(item).localname == f"{TYPES[spec.kind.value]}CharacteristicItem"
        kind = item.xpath("q:Attributes/q:AttributeStr[@name='ita.kind']/@value", namespaces=NS)
        assert kind == [spec.kind.value]
    statuses = set(doc.xpath("//q:CharacteristicMeasurements/*/q:Status/q:CharacteristicStatusEnum/text()",
                             namespaces=NS))
    assert statuses == {"PASS", "FAIL", "INDETERMINATE", "NOT_ANALYZED"}
    assert doc.xpath("//q:ActualComponent/q:SerialNumber/text()", namespaces=NS) == ["SN-0042"]
    assert doc.xpath("//q:InspectionTraceability/q:InspectionOperator/q:Name/text()",
                     namespaces=NS) == ["A. Lovelace"]
    # a hole's position: a diametrical zone in the frame of its datums A|B|C
    position = doc.xpath("//q:PositionCharacteristicDefinition", namespaces=NS)[0]
    assert position.find("q:ZoneShape/q:DiametricalZone", namespaces=NS) is not None
    frame = position.findtext("q:DatumReferenceFrameId", namespaces=NS)
    labels = doc.xpath(f"//q:DatumReferenceFrame[@id='{frame}']//q:DatumDefinitionId/text()", namespaces=NS)
    assert [doc.xpath(f"//q:DatumDefinition[@id='{i}']/q:DatumLabel/text()", namespaces=NS)[0]
            for i in labels] == ["A", "B", "C"]


def test_a_whole_part_that_conforms_passes(builtin_part, kinds, schema, tmp_path: Path) -> None:
    part = tmp_path / "part"
    part.mkdir()
    write_specs(part / "specs.csv", kinds)
    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as a:
        record_kinds_run(a, kinds, part, all_conform=True)
    out = tmp_path / "pass.qif"
    res = run("results", "last", "--runs-dir", str(runs), "--qif", str(out))
    assert res.exit_code == 0, res.output
    doc = valid(schema, out)
    check_against_archive(doc, runs)
    assert doc.xpath("//q:InspectionStatusEnum/text()", namespaces=NS) == ["PASS", "PASS"]


def test_a_whole_run_validates_and_reads_back_as_the_same_specs(builtin_part, schema, tmp_path: Path) -> None:
    """Every spec of the built-in part, each status: the document validates, holds every
    result, and its import gives back the part's specs (all fields but the note)."""
    specs = read_specs(builtin_part.specs_path)
    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as a:
        record_kinds_run(a, specs, builtin_part.directory)
    out = tmp_path / "own.qif"
    assert run("results", "last", "--runs-dir", str(runs), "--qif", str(out)).exit_code == 0
    check_against_archive(valid(schema, out), runs)
    res = run("spec", "import", str(out), "--out", str(tmp_path / "back"))
    assert res.exit_code == 0, res.output
    back = read_specs(tmp_path / "back" / "specs.csv")
    assert back == specs
    assert (tmp_path / "back" / "refused.csv").read_text(encoding="utf-8").strip() == \
        "id,qif_type,reason,qif_id,name,line"


def test_specs_the_part_no_longer_has_are_written_as_points(builtin_part, kinds, schema, tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    gone = tmp_path / "gone-part"
    with Archive.open(runs / "archive.sqlite") as a:
        record_kinds_run(a, kinds, gone)
    out = tmp_path / "gone.qif"
    res = run("results", "last", "--runs-dir", str(runs), "--qif", str(out))
    assert res.exit_code == 0, res.output
    assert "warning: cannot read the part's specs" in res.stderr
    doc = valid(schema, out)
    assert len(doc.xpath("//q:CharacteristicMeasurements/*", namespaces=NS)) == len(kinds)
    assert not doc.xpath("//q:CircleFeatureNominal", namespaces=NS)


def test_bad_run_or_path_is_one_error_line_and_no_file(builtin_part, kinds, tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as a:
        record_kinds_run(a, kinds[:3], builtin_part.directory)
    cases = [("nope", tmp_path / "a.qif"), ("last", tmp_path / "missing-dir" / "b.qif"), ("last", tmp_path)]
    for ref, target in cases:
        res = run("results", ref, "--runs-dir", str(runs), "--qif", str(target))
        assert res.exit_code == 2, res.output
        assert len(res.stderr.strip().splitlines()) == 1 and res.stderr.startswith("error: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]
    res = run("results", "last", "--runs-dir", str(tmp_path / "no-runs"), "--qif", str(tmp_path / "c.qif"))
    assert res.exit_code == 2 and not (tmp_path / "c.qif").exists()
    res = run("results", "last", "--runs-dir", str(runs), "--qif", str(tmp_path / "d.qif"), "--json")
    assert res.exit_code == 2 and not (tmp_path / "d.qif").exists()


def test_a_failure_while_writing_leaves_the_old_file(builtin_part, kinds, tmp_path: Path, monkeypatch) -> None:
    import ita.qif.results as results

    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as a:
        run_id = record_kinds_run(a, kinds[:3], builtin_part.directory)
    out = tmp_path / "keep.qif"
    out.write_text("old", encoding="utf-8")

    def interrupted(root):
        raise KeyboardInterrupt

    monkeypatch.setattr(results, "to_bytes", interrupted)
    with Archive.open(runs / "archive.sqlite", create=False) as a, pytest.raises(KeyboardInterrupt):
        results.export_run(a, run_id, out)
    assert out.read_text(encoding="utf-8") == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.qif", "runs"]
