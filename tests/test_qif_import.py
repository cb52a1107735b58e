"""`ita spec import FILE.qif --out DIR`: every characteristic of a QIF 3 file is one row
of DIR/specs.csv (ITA's specs) or DIR/refused.csv (with the reason); the NIST PMI test
models (../shared/qif/models/), a plan with items, and a file of every shape the rules
read (units, limits, references, pairs, origins); a file that is not QIF 3 writes nothing."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.specs.io import read_specs
from ita.specs.model import MeasurementKind as K

etree = pytest.importorskip("lxml.etree")

REPO = Path(__file__).resolve().parent.parent
QIF = REPO.parent / "shared" / "qif"
NS = {"q": "http://qifstandards.org/xsd/qif3"}


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def shared(*parts: str) -> Path:
    path = QIF.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} is absent (the shared folder ../shared/qif/ is not beside the checkout)")
    return path


def import_to(source: Path, out: Path, *more: str) -> tuple[list, list[dict]]:
    res = run("spec", "import", str(source), "--out", str(out), *more)
    assert res.exit_code == 0, res.output
    specs = read_specs(out / "specs.csv")
    with open(out / "refused.csv", encoding="utf-8", newline="") as f:
        refused = list(csv.DictReader(f))
    return specs, refused


def qif_id(spec) -> str:
    """The QIF id of the characteristic a spec came from (its note says)."""
    found = re.match(r"from QIF \w+ (\d+)", spec.note)
    assert found, spec.note
    return found.group(1)


def characteristics(path: Path) -> list[str]:
    """The ids of a file's characteristics as the import counts them, read independently:
    its items (and nominals no item names), else its nominals."""
    doc = etree.parse(str(path))
    items = doc.xpath("//q:Characteristics/q:CharacteristicItems/*", namespaces=NS)
    nominals = doc.xpath("//q:Characteristics/q:CharacteristicNominals/*", namespaces=NS)
    named = {i.findtext("q:CharacteristicNominalId", namespaces=NS).strip() for i in items}
    return [e.get("id") for e in items] + [e.get("id") for e in nominals if e.get("id") not in named]


def accounted(path: Path, specs, refused) -> None:
    """Every characteristic is in one file, once; nothing else is."""
    mapped = [qif_id(s) for s in specs]
    ids = [r["qif_id"] for r in refused] + sorted(set(mapped))
    assert sorted(ids) == sorted(characteristics(path))
    assert len({s.id for s in specs} | {r["id"] for r in refused}) == len(specs) + len(refused)


# ----------------------------------------------------------------------------- the NIST models
@pytest.mark.parametrize("model", ["nist_ctc_01_asme1_ap242.qif", "nist_ctc_03_asme1_ap242.qif",
                                   "nist_ftc_06_asme1_ap242.qif"])
def test_every_characteristic_of_a_nist_model_is_accounted_for(model: str, tmp_path: Path) -> None:
    path = shared("models", model)
    specs, refused = import_to(path, tmp_path / "out")
    accounted(path, specs, refused)
    assert len(specs) + len(refused) == len(characteristics(path))     # one row each
    assert specs and refused
    reasons = {r["qif_type"]: r["reason"] for r in refused}
    assert any(t.startswith(("Flatness", "SurfaceProfile")) for t in reasons)
    for t, reason in reasons.items():
        if t.startswith("Flatness"):
            assert reason.startswith("a form tolerance")
        if t.startswith("SurfaceProfile"):
            assert reason.startswith("a profile tolerance")
    for s in specs:
        assert s.kind in (K.HOLE_DIAMETER, K.HOLE_POSITION)       # these models give holes
        assert s.lower < s.upper and s.datum


def test_inch_targets_and_a_cylinders_entry_face(tmp_path: Path) -> None:
    """ctc_03 states its sizes in inches and its holes as cylinders from either face."""
    specs, _ = import_to(shared("models", "nist_ctc_03_asme1_ap242.qif"), tmp_path / "out")
    by = {qif_id(s): s for s in specs}
    hole = by["2047"]                      # 0.438 in +-0.005 in, axis from the top face down
    assert hole.kind is K.HOLE_DIAMETER and hole.nominal == pytest.approx(11.1252)
    assert (hole.lower, hole.upper) == (pytest.approx(-0.127), pytest.approx(0.127))
    assert hole.normal == (0.0, 0.0, 1.0) and hole.point[2] == pytest.approx(1.90754, abs=1e-5)
    big = by["2082"]                       # its axis starts at the bottom: the entry is the far end
    assert big.normal == (0.0, 0.0, 1.0) and big.point[2] == pytest.approx(78.10754, abs=1e-5)
    position = next(s for s in specs if qif_id(s) == "2085")
    assert (position.kind, position.nominal, position.lower, position.upper, position.datum) == \
        (K.HOLE_POSITION, 0.0, 0.0, pytest.approx(0.06), "D|B|C")


def test_patterns_are_refused_or_expanded_one_spec_per_feature(tmp_path: Path) -> None:
    path = shared("models", "nist_ctc_03_asme1_ap242.qif")
    specs, refused = import_to(path, tmp_path / "one")
    patterns = [r for r in refused if r["reason"].startswith("applies to")]
    assert len(patterns) == 4
    wide, refused_wide = import_to(path, tmp_path / "all", "--expand-patterns")
    accounted(path, wide, refused_wide)
    assert len(refused_wide) == len(refused) - 4
    four = [s for s in wide if qif_id(s) == "2058"]           # a diameter on four holes
    assert [s.id for s in four] == ["2058.1", "2058.2", "2058.3", "2058.4"]
    assert len({s.point for s in four}) == 4 and [s.nominal for s in four] == [15.875] * 4


def test_a_plan_with_items_counts_its_items(tmp_path: Path) -> None:
    path = shared("samples", "WIDGET_QIF_PLAN.QIF")
    specs, refused = import_to(path, tmp_path / "out")
    assert len(specs) + len(refused) == 26
    accounted(path, specs, refused)
    # items are named by their balloon numbers: the ids; features by their items' names
    assert all(re.fullmatch(r"\d+", s.id) for s in specs)
    assert {"CYLINDER6", "DATUM_J"} <= {s.feature for s in specs}


# ----------------------------------------------------------------------------- every shape
HEADER = """<?xml version="1.0" encoding="UTF-8"?>
<QIFDocument xmlns="http://qifstandards.org/xsd/qif3" versionQIF="3.0.0" idMax="999">
  <QPId>00000000-0000-0000-0000-000000000001</QPId>
  <FileUnits><PrimaryUnits>
    <LinearUnit><SIUnitName>meter</SIUnitName><UnitName>inch</UnitName>
      <UnitConversion><Factor>0.0254</Factor></UnitConversion></LinearUnit>
    <PMILinearUnit><SIUnitName>meter</SIUnitName><UnitName>mm</UnitName>
      <UnitConversion><Factor>0.001</Factor></UnitConversion></PMILinearUnit>
  </PrimaryUnits>
  <OtherUnits n="1"><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>thou</UnitName>
      <UnitConversion><Factor>0.0000254</Factor></UnitConversion></LinearUnit></OtherUnits></FileUnits>
  <DatumDefinitions n="2">
    <DatumDefinition id="1"><DatumLabel>A</DatumLabel></DatumDefinition>
    <DatumDefinition id="2"><DatumLabel>B</DatumLabel></DatumDefinition>
  </DatumDefinitions>
  <DatumReferenceFrames n="1"><DatumReferenceFrame id="3"><Datums n="2">
    <Datum><SimpleDatum><DatumDefinitionId>2</DatumDefinitionId><MaterialModifier>NONE</MaterialModifier>
      <ReferencedComponent>NOMINAL</ReferencedComponent></SimpleDatum>
      <Precedence><PrecedenceEnum>SECONDARY</PrecedenceEnum></Precedence></Datum>
    <Datum><SimpleDatum><DatumDefinitionId>1</DatumDefinitionId><MaterialModifier>NONE</MaterialModifier>
      <ReferencedComponent>NOMINAL</ReferencedComponent></SimpleDatum>
      <Precedence><PrecedenceEnum>PRIMARY</PrecedenceEnum></Precedence></Datum>
  </Datums></DatumReferenceFrame></DatumReferenceFrames>
"""

FEATURES = """
  <Features>
    <FeatureDefinitions n="6">
      <CylinderFeatureDefinition id="10"><InternalExternal>INTERNAL</InternalExternal>
        <Diameter>0.25</Diameter><Length>0.1</Length></CylinderFeatureDefinition>
      <CylinderFeatureDefinition id="11"><InternalExternal>EXTERNAL</InternalExternal>
        <Diameter>0.5</Diameter></CylinderFeatureDefinition>
      <PlaneFeatureDefinition id="12"/>
      <OppositeParallelLinesFeatureDefinition id="13"><InternalExternal>EXTERNAL</InternalExternal>
        <Width>0.12</Width><EndType><SlotEndEnum>OPEN</SlotEndEnum></EndType></OppositeParallelLinesFeatureDefinition>
      <OppositeParallelPlanesFeatureDefinition id="14"><InternalExternal>INTERNAL</InternalExternal>
        <Width>0.4</Width><EndType><SlotEndEnum>ROUND</SlotEndEnum></EndType></OppositeParallelPlanesFeatureDefinition>
      <SphereFeatureDefinition id="15"><InternalExternal>EXTERNAL</InternalExternal>
        <Diameter>1</Diameter></SphereFeatureDefinition>
    </FeatureDefinitions>
    <FeatureNominals n="9">
      <CylinderFeatureNominal id="20"><Name>HOLE-1</Name><FeatureDefinitionId>10</FeatureDefinitionId>
        <Axis><AxisPoint>1 2 0</AxisPoint><Direction>0 0 1</Direction></Axis></CylinderFeatureNominal>
      <CylinderFeatureNominal id="21"><Name>PIN</Name><FeatureDefinitionId>11</FeatureDefinitionId>
        <Axis><AxisPoint>3 3 0.1</AxisPoint><Direction>0 0 1</Direction></Axis></CylinderFeatureNominal>
      <PlaneFeatureNominal id="22"><Name>TOP</Name><FeatureDefinitionId>12</FeatureDefinitionId>
        <Location>2 2 0.1</Location><Normal>0 0 1</Normal></PlaneFeatureNominal>
      <PlaneFeatureNominal id="23"><Name>BOTTOM</Name><FeatureDefinitionId>12</FeatureDefinitionId>
        <Location>2 2 0</Location><Normal>0 0 -1</Normal></PlaneFeatureNominal>
      <PlaneFeatureNominal id="24"><Name>EDGE</Name><FeatureDefinitionId>12</FeatureDefinitionId>
        <Location>1.5 0 0.05</Location><Normal>1 0 0</Normal></PlaneFeatureNominal>
      <OppositeParallelLinesFeatureNominal id="25"><Name>RIB</Name><FeatureDefinitionId>13</FeatureDefinitionId>
        <CenterLine><StartPoint>0 5 1</StartPoint><Vector>1 0 0</Vector></CenterLine><Normal>0 0 1</Normal>
      </OppositeParallelLinesFeatureNominal>
      <OppositeParallelPlanesFeatureNominal id="26"><Name>SLOT</Name><FeatureDefinitionId>14</FeatureDefinitionId>
        <CenterPlane><Point>0 8 0.05</Point><Normal>0 1 0</Normal></CenterPlane></OppositeParallelPlanesFeatureNominal>
      <SphereFeatureNominal id="27"><Name>BALL</Name><FeatureDefinitionId>15</FeatureDefinitionId>
        <Location>9 9 9</Location></SphereFeatureNominal>
      <PlaneFeatureNominal id="28"><Name>RIB-TOP</Name><FeatureDefinitionId>12</FeatureDefinitionId>
        <Location>0 5 1</Location><Normal>0 0 1</Normal></PlaneFeatureNominal>
    </FeatureNominals>
  </Features>
"""


def linear(stem: str, did: int, tolerance: str) -> str:
    return f"<{stem}CharacteristicDefinition id=\"{did}\">{tolerance}</{stem}CharacteristicDefinition>"


def nominal(stem: str, nid: int, did: int, features: str, name: str, target: str = "", more: str = "") -> str:
    return (f"<{stem}CharacteristicNominal id=\"{nid}\"><CharacteristicDefinitionId>{did}</CharacteristicDefinitionId>"
            f"{features}<Name>{name}</Name>{target}{more}</{stem}CharacteristicNominal>")


def ids(*refs: int) -> str:
    return f"<FeatureNominalIds n=\"{len(refs)}\">" + "".join(f"<Id>{r}</Id>" for r in refs) + "</FeatureNominalIds>"


DEVIATIONS = ("<Tolerance><MaxValue>0.05</MaxValue><MinValue>-0.05</MinValue>"
              "<DefinedAsLimit>false</DefinedAsLimit></Tolerance>")


def shapes_document() -> str:
    defs = [
        linear("Diameter", 100, "<Tolerance><MaxValue>6.4</MaxValue><MinValue>6.3</MinValue>"
                                "<DefinedAsLimit>true</DefinedAsLimit></Tolerance>"),
        "<PositionCharacteristicDefinition id=\"101\"><ToleranceValue linearUnit=\"thou\">10</ToleranceValue>"
        "<DatumReferenceFrameId>3</DatumReferenceFrameId><MaterialCondition>MAXIMUM</MaterialCondition>"
        "<ZoneShape><DiametricalZone/></ZoneShape></PositionCharacteristicDefinition>",
        linear("DistanceBetween", 102, DEVIATIONS),
        linear("DistanceBetween", 103, "<Tolerance><DefinitionId>900</DefinitionId>"
                                       "<DefinedAsLimit>false</DefinedAsLimit></Tolerance>"),
        linear("Height", 104, DEVIATIONS),
        linear("Width", 105, DEVIATIONS),
        linear("Width", 106, DEVIATIONS),
        linear("Diameter", 107, DEVIATIONS),
        "<FlatnessCharacteristicDefinition id=\"108\"><ToleranceValue>0.1</ToleranceValue>"
        "</FlatnessCharacteristicDefinition>",
        linear("Diameter", 109, "<Tolerance><MaxValue>0.1</MaxValue><DefinedAsLimit>false</DefinedAsLimit>"
                                "</Tolerance>"),
        linear("Diameter", 110, "<NonTolerance>MEASURED</NonTolerance>"),
        linear("Diameter", 111, "<Tolerance><MaxValue linearUnit=\"furlong\">1</MaxValue><MinValue>0</MinValue>"
                                "<DefinedAsLimit>false</DefinedAsLimit></Tolerance>"),
        linear("Height", 112, DEVIATIONS),
    ]
    noms = [
        nominal("Diameter", 200, 100, ids(20), "HOLE DIA", "<TargetValue>6.35</TargetValue>"),
        nominal("Position", 201, 101, ids(20), "POS-1"),
        nominal("DistanceBetween", 202, 102, "", "EDGE-1", "<TargetValue>12.7</TargetValue>",
                "<FeatureNominalPairs n=\"1\"><FeaturePair><FirstFeature>24</FirstFeature>"
                "<SecondFeature>20</SecondFeature></FeaturePair></FeatureNominalPairs>"
                "<AnalysisMode>ONEDIMENSIONAL</AnalysisMode>"),
        nominal("DistanceBetween", 203, 103, ids(22, 23), "WEB-T", "<TargetValue>2.54</TargetValue>",
                "<AnalysisMode>ONEDIMENSIONAL</AnalysisMode>"),
        nominal("Height", 204, 104, ids(28), "RIB-H", "<TargetValue>25.4</TargetValue>"),
        nominal("Width", 205, 105, ids(25), "RIB-W", "<TargetValue>3.048</TargetValue>"),
        nominal("Width", 206, 106, ids(26), "SLOT-W", "<TargetValue>10.16</TargetValue>"),
        nominal("Diameter", 207, 107, ids(21), "PIN-D", "<TargetValue>12.7</TargetValue>"),
        nominal("Flatness", 208, 108, ids(22), "FLAT"),
        nominal("Diameter", 209, 109, ids(20), "ONE-SIDED", "<TargetValue>6.35</TargetValue>"),
        nominal("Diameter", 210, 110, ids(20), "REF-DIA", "<TargetValue>6.35</TargetValue>"),
        nominal("Diameter", 211, 111, ids(20), "FURLONGS", "<TargetValue>6.35</TargetValue>"),
        nominal("Diameter", 212, 107, ids(27), "BALL-D", "<TargetValue>25.4</TargetValue>"),
        nominal("Diameter", 213, 107, ids(404), "LOST", "<TargetValue>1</TargetValue>"),
        nominal("Diameter", 214, 777, ids(20), "NO-DEF", "<TargetValue>1</TargetValue>"),
        nominal("Height", 215, 112, ids(22), "NOT-ABOVE-A", "<TargetValue>25.4</TargetValue>"),
    ]
    chars = ("<Characteristics><FormalStandardId>1</FormalStandardId>"
             f"<CharacteristicDefinitions n=\"{len(defs)}\">" + "".join(defs) + "</CharacteristicDefinitions>"
             "<DefaultToleranceDefinitions n=\"1\"><LinearTolerance id=\"900\"><MaxValue>0.1</MaxValue>"
             "<MinValue>-0.1</MinValue></LinearTolerance></DefaultToleranceDefinitions>"
             f"<CharacteristicNominals n=\"{len(noms)}\">" + "".join(noms) + "</CharacteristicNominals>"
             "</Characteristics>")
    return HEADER + FEATURES + chars + "</QIFDocument>\n"


@pytest.fixture()
def shapes_file(tmp_path: Path) -> Path:
    path = tmp_path / "shapes.qif"
    path.write_text(shapes_document(), encoding="utf-8")
    return path


def test_every_shape_the_rules_read(shapes_file: Path, tmp_path: Path) -> None:
    specs, refused = import_to(shapes_file, tmp_path / "out")
    accounted(shapes_file, specs, refused)
    by = {s.id: s for s in specs}
    why = {r["id"]: r["reason"] for r in refused}
    assert sorted(by) == ["200", "EDGE-1", "POS-1", "RIB-H", "RIB-W", "WEB-T"]
    hole = by["200"]                       # "HOLE DIA" is no spec id: the QIF id; limits, mm
    assert (hole.kind, hole.nominal, hole.lower, hole.upper) == (K.HOLE_DIAMETER, 6.35, -0.05, 0.05)
    assert hole.point == (25.4, 50.8, 2.54) and hole.normal == (0.0, 0.0, 1.0)   # the far end, inches
    assert hole.feature == "HOLE-1"
    pos = by["POS-1"]
    assert (pos.kind, pos.upper, pos.datum) == (K.HOLE_POSITION, 0.254, "A|B")   # thou; by precedence
    assert "MAXIMUM not applied" in pos.note
    edge = by["EDGE-1"]
    assert edge.kind is K.EDGE_DISTANCE and edge.direction == (1.0, 0.0, 0.0) and edge.nominal == 12.7
    web = by["WEB-T"]
    assert (web.kind, web.nominal, web.lower, web.upper) == (K.WEB_THICKNESS, 2.54, -0.1, 0.1)
    assert web.normal == (0.0, 0.0, 1.0)
    height = by["RIB-H"]
    assert (height.kind, height.point) == (K.STIFFENER_HEIGHT, (0.0, 127.0, 25.4))
    width = by["RIB-W"]
    assert width.kind is K.STIFFENER_WIDTH and width.direction == (0.0, -1.0, 0.0) and width.normal == (0, 0, 1)
    assert why["SLOT-W"].startswith("the width of a slot")
    assert why["PIN-D"].startswith("on an external cylinder")
    assert why["FLAT"].startswith("a form tolerance (flatness)")
    assert why["ONE-SIDED"].startswith("a one-sided tolerance")
    assert why["REF-DIA"].startswith("no tolerance (NonTolerance MEASURED)")
    assert "furlong" in why["FURLONGS"]
    assert why["BALL-D"].startswith("on a Sphere feature")
    assert why["LOST"].startswith("its feature nominal 404 is not in the file")
    assert why["NO-DEF"].startswith("its definition 777 is not in the file")
    assert why["NOT-ABOVE-A"].startswith("a height of 25.4 mm whose face lies 2.54 mm above datum A")


def test_a_file_without_units_is_read_in_mm_with_a_warning(tmp_path: Path) -> None:
    text = re.sub(r"<FileUnits>.*?</FileUnits>", "", shapes_document(), flags=re.S)
    text = text.replace(' linearUnit="thou"', "")
    path = tmp_path / "mm.qif"
    path.write_text(text, encoding="utf-8")
    res = run("spec", "import", str(path), "--out", str(tmp_path / "out"))
    assert res.exit_code == 0, res.output
    assert "warning: the file states no length unit" in res.stderr
    hole = next(s for s in read_specs(tmp_path / "out" / "specs.csv") if s.id == "200")
    assert hole.point == (1.0, 2.0, 0.1)


# ----------------------------------------------------------------------------- bad input
def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("content, message", [
    ("hello, not XML", "not a QIF file: not XML"),
    ("<?xml version='1.0'?><catalog><book/></catalog>", "not a QIF file: the root element is <catalog>"),
    ("<QIFDocument xmlns='http://qifstandards.org/xsd/qif2' versionQIF='2.1.0'/>", "a QIF 2 document"),
    ("<QIFDocument xmlns='http://qifstandards.org/xsd/qif3' versionQIF='4.0.0'/>", "QIF version 4.0.0"),
    ("<QIFDocument xmlns='http://qifstandards.org/xsd/qif3'/>", "no versionQIF"),
    ("<QIFDocument xmlns='http://qifstandards.org/xsd/qif3' versionQIF='3.0.0'><QPId id='1'/><QPId id='1'/>"
     "</QIFDocument>", "id 1 is used twice"),
    ("<QIFDocument xmlns='http://qifstandards.org/xsd/qif3' versionQIF='3.0.0'>"
     "<Characteristics", "not a QIF file: not XML"),
])
def test_a_file_that_is_not_qif_3_is_one_error_line_and_nothing_written(content: str, message: str,
                                                                         tmp_path: Path) -> None:
    source = _write(tmp_path / "in.qif", content)
    out = tmp_path / "out"
    res = run("spec", "import", str(source), "--out", str(out))
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {source}") and message in lines[0], lines
    assert not out.exists()


def test_missing_file_and_bad_out_are_one_error_line(shapes_file: Path, tmp_path: Path) -> None:
    res = run("spec", "import", str(tmp_path / "nothing.qif"), "--out", str(tmp_path / "o"))
    assert res.exit_code == 2 and res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1
    blocker = _write(tmp_path / "a-file", "x")
    res = run("spec", "import", str(shapes_file), "--out", str(blocker))
    assert res.exit_code == 2 and res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1
    assert blocker.read_text() == "x" and not (tmp_path / "o").exists()
    res = run("spec", "import", str(shapes_file))                 # a QIF file goes with --out
    assert res.exit_code == 2


def test_entities_are_not_resolved(tmp_path: Path) -> None:
    secret = _write(tmp_path / "secret.txt", "TOP-SECRET")
    text = shapes_document().replace(
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<?xml version="1.0" encoding="UTF-8"?><!DOCTYPE QIFDocument [<!ENTITY s SYSTEM "{secret.as_uri()}">]>'
    ).replace("<Name>HOLE-1</Name>", "<Name>HOLE&s;</Name>")
    source = _write(tmp_path / "xxe.qif", text)
    res = run("spec", "import", str(source), "--out", str(tmp_path / "out"))
    assert res.exit_code == 0, res.output
    for name in ("specs.csv", "refused.csv"):
        assert "TOP-SECRET" not in (tmp_path / "out" / name).read_text(encoding="utf-8")
