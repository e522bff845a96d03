"""Drill plans in and out (planning.drilling.plans): IREDES DRPPlan files with their CRC32
checksum, CSV and JSON; the errors name the element, hole, row and column at fault."""

from __future__ import annotations

import json
import re
import zlib

import numpy as np
import pytest

from kinematics.errors import FieldError
from planning.drilling.plans import (
    MAX_HOLES,
    DrillPlan,
    Hole,
    PlanFormatError,
    PlanTooLargeError,
    iredes_checksum,
    read_csv,
    read_iredes,
    read_iredes_with_assignments,
    read_json,
    to_csv,
    write_iredes,
)

# ---- fixtures ------------------------------------------------------------------------------
HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<DRPPlan xmlns:IR="http://www.iredes.org/xml" xmlns="http://www.iredes.org/xml/DrillRig" \
IRVersion="V 1.0" IRDownwCompat="V 1.0">
  <IR:GenHead>
    <IR:FileCreateDate>2026-11-30T07:00:00</IR:FileCreateDate>
    <IR:IRversion DownwCompat="V 1.0">V 1.0</IR:IRversion>
  </IR:GenHead>
  <IR:PlanId>T-1</IR:PlanId>
  <IR:PlanName>Test round</IR:PlanName>
  <IR:Comment>two holes</IR:Comment>
  <DrillPosPlan IRVersion="V 1.0" IRDownwCompat="V 1.0">
    <PositionData>
      <Coordsystem>
        <IR:CoordSysName>site</IR:CoordSysName>
        <IR:TMatrix>
          <IR:Col><IR:x>1.000</IR:x><IR:y>0.000</IR:y><IR:z>0.000</IR:z><IR:w>0.000</IR:w></IR:Col>
          <IR:Col><IR:x>0.000</IR:x><IR:y>1.000</IR:y><IR:z>0.000</IR:z><IR:w>0.000</IR:w></IR:Col>
          <IR:Col><IR:x>0.000</IR:x><IR:y>0.000</IR:y><IR:z>1.000</IR:z><IR:w>0.000</IR:w></IR:Col>
          <IR:Col><IR:x>10.000</IR:x><IR:y>-2.500</IR:y><IR:z>0.125</IR:z><IR:w>1.000</IR:w></IR:Col>
        </IR:TMatrix>
        <IR:CsysType>L</IR:CsysType>
      </Coordsystem>
      <PlanIdRef />
      <Bearing>0.000</Bearing>
    </PositionData>
  </DrillPosPlan>
  <DrillPlan>
    <NumberOfHoles>{count}</NumberOfHoles>
"""
HOLE = """    <Hole>
      <HoleId>{id}</HoleId>
      <HoleName>{name}</HoleName>
      <StartPoint>
        <IR:PointX>{cx}</IR:PointX>
        <IR:PointY>{cy}</IR:PointY>
        <IR:PointZ>{cz}</IR:PointZ>
      </StartPoint>
      <EndPoint>
        <IR:PointX>{tx}</IR:PointX>
        <IR:PointY>{ty}</IR:PointY>
        <IR:PointZ>{tz}</IR:PointZ>
      </EndPoint>
      <TypeOfHole>{type}</TypeOfHole>
      <DrillBitDia>{dia}</DrillBitDia>
      <MwdOn>0</MwdOn>
      <HoleOptions />
    </Hole>
"""
TAIL = """    <EquipmentData>
      <IR:OptionData />
    </EquipmentData>
  </DrillPlan>
  <IR:GenTrailer>
    <IR:FileCloseDate>2026-11-30T07:00:00</IR:FileCloseDate>
    <IR:ChkSum>0</IR:ChkSum>
  </IR:GenTrailer>
</DRPPlan>
"""
HOLES = [
    {"id": "1", "name": "C001", "cx": "512.000", "cy": "-3.300", "cz": "20.300",
     "tx": "516.494", "ty": "-3.536", "tz": "20.300", "type": "Contour", "dia": "45"},
    {"id": "2", "name": "R001", "cx": "512.000", "cy": "0.150", "cz": "21.000",
     "tx": "516.700", "ty": "0.150", "tz": "21.000", "type": "Reamer", "dia": "102"},
]


def _signed(text: str) -> bytes:
    """``text`` (with ``<IR:ChkSum>0</IR:ChkSum>``) as CRLF bytes with its CRC32 filled in,
    computed here independently of the reader."""
    data = text.replace("\r\n", "\n").replace("\n", "\r\n").encode()
    placeholder = re.compile(rb"(<(?:\w+:)?ChkSum>)0(</)")
    assert len(placeholder.findall(data)) == 1
    crc = zlib.crc32(data)
    return placeholder.sub(lambda m: m.group(1) + str(crc).encode() + m.group(2), data)


def iredes_text(holes=HOLES, count: int | None = None, head: str = HEAD) -> str:
    body = "".join(HOLE.format(**h) for h in holes)
    return head.replace("{count}", str(len(holes) if count is None else count)) + body + TAIL


def iredes_file(holes=HOLES, **kwargs) -> bytes:
    return _signed(iredes_text(holes, **kwargs))


def _rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.fixture
def plan() -> DrillPlan:
    """Three holes, sub-mm coordinates, a rotated frame, text that XML must escape."""
    frame = np.eye(4)
    frame[:3, :3] = _rotation_z(0.3)
    frame[:3, 3] = [1234.5678, -98.7, 20_000.0]
    holes = (
        Hole("1", "C<1> & co", [512_000.0, -3_300.0, 20_300.0],
             [516_494.0, -3_536.0, 20_300.0], "Contour", 45.0),
        Hole("K-2", "cut", [512_000.25, 0.125, 21_000.0], [516_700.0, 0.1, 21_000.3333],
             "Cut", 51.5),
        Hole("3", "", [512_000.0, 1_000.0, 22_000.0], [516_500.0, 1_000.0, 22_000.0], "",
             None),
    )
    return DrillPlan("R-7", "Round \"7\"", frame, "site", holes)


# ---- the data structure --------------------------------------------------------------------
def test_hole_axis_and_depth():
    h = Hole("1", "a", [0.0, 0.0, 0.0], [3000.0, 4000.0, 0.0], "Stoping", 45)
    assert h.depth_mm == 5000.0
    np.testing.assert_allclose(h.axis, [0.6, 0.8, 0.0])
    assert h.collar.dtype == np.float64 and not h.collar.flags.writeable
    with pytest.raises(ValueError, match="zero depth"):
        Hole("9", "", [1.0, 2.0, 3.0], [1.0, 2.0, 3.0])


def test_plan_accessors(plan):
    assert plan.ids() == ["1", "K-2", "3"]
    assert plan.collars().shape == (3, 3) and plan.toes().shape == (3, 3)
    np.testing.assert_array_equal(plan.collars()[1], [512_000.25, 0.125, 21_000.0])
    np.testing.assert_allclose(plan.depths()[2], 4500.0)
    np.testing.assert_allclose(plan.axes()[2], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="used twice"):
        DrillPlan("p", "", np.eye(4), "", (plan.holes[0], plan.holes[0]))


def test_in_frame_expresses_the_holes_in_the_rigs_frame():
    holes = (Hole("1", "", [512_000.0, -3_300.0, 20_300.0], [516_500.0, -3_300.0, 20_300.0]),)
    site = DrillPlan("p", "", np.eye(4), "site", holes)
    rig = np.eye(4)
    rig[:3, 3] = [503_000.0, 0.0, 21_500.0]
    local = site.in_frame(rig, frame_name="rig")
    np.testing.assert_allclose(local.collars()[0], [9_000.0, -3_300.0, -1_200.0])
    np.testing.assert_allclose(local.toes()[0], [13_500.0, -3_300.0, -1_200.0])
    assert local.frame_name == "rig"
    np.testing.assert_allclose(local.frame, rig)  # identity @ rig
    # A rig turned 90° about z: its x axis is the site's y axis.
    rig[:3, :3] = _rotation_z(np.pi / 2)
    turned = site.in_frame(rig)
    assert turned.frame_name == "site"
    np.testing.assert_allclose(turned.collars()[0], [-3_300.0, -9_000.0, -1_200.0], atol=1e-6)
    np.testing.assert_allclose(turned.holes[0].axis, [0.0, -1.0, 0.0], atol=1e-12)
    back = turned.in_frame(np.linalg.inv(rig))
    np.testing.assert_allclose(back.collars(), site.collars(), atol=1e-6)


# ---- IREDES: reading -----------------------------------------------------------------------
def test_reads_an_iredes_plan_in_mm():
    plan = read_iredes(iredes_file())
    assert (plan.plan_id, plan.name, plan.frame_name) == ("T-1", "Test round", "site")
    assert plan.ids() == ["1", "2"]
    h = plan.holes[0]
    assert (h.name, h.type, h.diameter_mm) == ("C001", "Contour", 45.0)
    np.testing.assert_array_equal(h.collar, [512_000.0, -3_300.0, 20_300.0])
    np.testing.assert_array_equal(h.toe, [516_494.0, -3_536.0, 20_300.0])
    assert plan.holes[1].diameter_mm == 102.0
    expected = np.eye(4)
    expected[:3, 3] = [10_000.0, -2_500.0, 125.0]  # metres in the file
    np.testing.assert_array_equal(plan.frame, expected)


def test_reads_text_as_well_as_bytes():
    data = iredes_file()
    assert read_iredes(data.decode()) == read_iredes(data)


def test_namespace_prefixes_and_unknown_elements_do_not_matter():
    text = iredes_text().replace("IR:", "iredes:").replace("xmlns:IR=", "xmlns:iredes=")
    text = text.replace("<MwdOn>0</MwdOn>", '<V:Feed xmlns:V="urn:vendor"><V:Bar>1</V:Bar>'
                        "</V:Feed><MwdOn>0</MwdOn>")
    assert read_iredes(_signed(text)).holes == read_iredes(iredes_file()).holes


def test_the_crc32_rule_is_that_of_the_file_with_0_in_place_of_the_checksum():
    unsigned = iredes_text().replace("\n", "\r\n").encode()
    expected = zlib.crc32(unsigned)   # computed here, not by the code under test
    signed = unsigned.replace(b"<IR:ChkSum>0</IR:ChkSum>",
                              f"<IR:ChkSum>{expected}</IR:ChkSum>".encode())
    assert iredes_checksum(signed) == expected
    assert read_iredes(signed).plan_id == "T-1"
    # Any other value is refused.
    wrong = signed.replace(f">{expected}<".encode(), f">{expected ^ 1}<".encode())
    with pytest.raises(PlanFormatError, match="ChkSum"):
        read_iredes(wrong)


def test_a_changed_file_fails_its_checksum_naming_chksum():
    changed = iredes_file().replace(b"<IR:PointY>-3.536</IR:PointY>",
                                    b"<IR:PointY>-3.537</IR:PointY>")
    with pytest.raises(PlanFormatError, match="ChkSum") as info:
        read_iredes(changed)
    assert info.value.loc == ("GenTrailer", "ChkSum")
    assert isinstance(info.value, FieldError) and isinstance(info.value, ValueError)
    # Not verified: read as it is, the changed value included.
    plan = read_iredes(changed, verify_checksum=False)
    assert plan.holes[0].toe[1] == -3_537.0


def test_line_endings_changed_on_the_way_fail_the_checksum():
    crlf = iredes_file()
    with pytest.raises(PlanFormatError, match="ChkSum"):
        read_iredes(crlf.replace(b"\r\n", b"\n"))


def test_a_missing_checksum_is_named_unless_not_verified():
    text = iredes_text().replace("    <IR:ChkSum>0</IR:ChkSum>\n", "")
    with pytest.raises(PlanFormatError, match="ChkSum") as info:
        read_iredes(text)
    assert info.value.loc == ("GenTrailer", "ChkSum")
    assert len(read_iredes(text, verify_checksum=False)) == 2


@pytest.mark.parametrize("doctype", [
    '<!DOCTYPE DRPPlan [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;">]>',
    '<!DOCTYPE DRPPlan SYSTEM "file:///etc/passwd">',
    '<!DOCTYPE DRPPlan [<!ENTITY x SYSTEM "file:///etc/passwd">]>',
])
def test_doctype_and_entities_are_refused(doctype):
    text = iredes_text().replace("<DRPPlan ", doctype + "\n<DRPPlan ", 1)
    text = text.replace("<IR:PlanName>Test round", "<IR:PlanName>&b;" if "b " in doctype
                        else "<IR:PlanName>Test round")
    with pytest.raises(PlanFormatError, match="DOCTYPE"):
        read_iredes(text, verify_checksum=False)


def test_deep_nesting_is_refused():
    deep = "<a>" * 100 + "</a>" * 100
    text = iredes_text().replace("<MwdOn>0</MwdOn>", deep, 1)
    with pytest.raises(PlanFormatError, match="nests"):
        read_iredes(text, verify_checksum=False)


def test_not_xml_and_not_a_plan():
    with pytest.raises(PlanFormatError, match="not well-formed"):
        read_iredes(b"<DRPPlan><DrillPlan></DRPPlan>")
    with pytest.raises(PlanFormatError, match="DRPPlan") as info:
        read_iredes(b"<robot name='x'/>", verify_checksum=False)
    assert info.value.loc == ("robot",)


def test_number_of_holes_must_match():
    with pytest.raises(PlanFormatError, match="NumberOfHoles") as info:
        read_iredes(iredes_file(count=3))
    assert info.value.loc == ("DrillPlan", "NumberOfHoles")


def test_northing_in_x_swaps_x_and_y():
    plain = read_iredes(iredes_file())
    swapped = read_iredes(iredes_file(), northing_in_x=True)
    np.testing.assert_array_equal(swapped.collars()[:, [1, 0, 2]], plain.collars())
    np.testing.assert_array_equal(swapped.toes()[0], [-3_536.0, 516_494.0, 20_300.0])
    # The TMatrix translation too (x and y swapped), the rotation kept a rotation.
    np.testing.assert_array_equal(swapped.frame[:3, 3], [-2_500.0, 10_000.0, 125.0])
    np.testing.assert_array_equal(swapped.frame[:3, :3], np.eye(3))


def test_a_zero_depth_hole_is_named():
    holes = [HOLES[0], {**HOLES[1], "id": "7", "tx": "512.000", "ty": "0.150", "tz": "21.000"}]
    with pytest.raises(PlanFormatError, match="'7'.*zero depth") as info:
        read_iredes(iredes_file(holes))
    assert info.value.loc == ("DrillPlan", "Hole[7]")
    assert info.value.hole_id == "7"


def test_a_bad_number_names_its_element_and_hole():
    holes = [HOLES[0], {**HOLES[1], "ty": "0,150"}]
    with pytest.raises(PlanFormatError, match="'2'") as info:
        read_iredes(iredes_file(holes))
    assert info.value.loc == ("DrillPlan", "Hole[2]", "EndPoint", "PointY")
    assert info.value.hole_id == "2"


def test_a_missing_element_is_named():
    text = iredes_text().replace("""      <EndPoint>
        <IR:PointX>516.700</IR:PointX>
        <IR:PointY>0.150</IR:PointY>
        <IR:PointZ>21.000</IR:PointZ>
      </EndPoint>
""", "")
    with pytest.raises(PlanFormatError, match="EndPoint") as info:
        read_iredes(_signed(text))
    assert info.value.loc == ("DrillPlan", "Hole[2]", "EndPoint")


def test_duplicate_hole_ids_are_named():
    with pytest.raises(PlanFormatError, match="used by holes number 1 and 2") as info:
        read_iredes(iredes_file([HOLES[0], {**HOLES[1], "id": "1"}]))
    assert info.value.loc == ("DrillPlan", "Hole[1]", "HoleId")


def test_a_tmatrix_that_is_not_a_rigid_transform_is_named():
    head = HEAD.replace("<IR:Col><IR:x>1.000</IR:x>", "<IR:Col><IR:x>2.000</IR:x>", 1)
    with pytest.raises(PlanFormatError, match="rotation") as info:
        read_iredes(iredes_file(head=head))
    assert info.value.loc == ("DrillPosPlan", "PositionData", "Coordsystem", "TMatrix")


def test_more_than_max_holes_is_too_large():
    holes = [{**HOLES[0], "id": str(k)} for k in range(MAX_HOLES + 1)]
    with pytest.raises(PlanTooLargeError, match="5,001 holes"):
        read_iredes(iredes_text(holes), verify_checksum=False)


# ---- IREDES: writing -----------------------------------------------------------------------
def test_round_trip(plan):
    text = write_iredes(plan)
    assert read_iredes(text) == plan
    assert read_iredes(text.encode()) == plan


def test_round_trip_of_an_iredes_file():
    first = read_iredes(iredes_file())
    again = read_iredes(write_iredes(first))
    assert again == first


def test_written_file_is_the_standards_layout(plan):
    text = write_iredes(plan, created="2026-11-30T07:00:00")
    assert text.startswith('<?xml version="1.0" encoding="UTF-8"?>\r\n<DRPPlan ')
    assert "\n" not in text.replace("\r\n", "")   # CRLF line ends, as rigs write them
    lines = text.split("\r\n")
    assert "    <NumberOfHoles>3</NumberOfHoles>" in lines
    assert "        <IR:PointX>512.000</IR:PointX>" in lines      # 512,000 mm
    assert "        <IR:PointY>-3.536</IR:PointY>" in lines       # -3,536 mm
    assert "        <IR:PointX>512.00025</IR:PointX>" in lines    # 512,000.25 mm
    assert "        <IR:PointZ>21.0003333</IR:PointZ>" in lines   # 21,000.3333 mm
    assert "      <DrillBitDia>45</DrillBitDia>" in lines
    assert "      <DrillBitDia>51.5</DrillBitDia>" in lines
    assert "      <HoleName>C&lt;1&gt; &amp; co</HoleName>" in lines
    assert "    <IR:FileCreateDate>2026-11-30T07:00:00</IR:FileCreateDate>" in lines
    # The checksum: CRC32 of the file with 0 in its place, computed here.
    written = re.search(r"<IR:ChkSum>(\d+)</IR:ChkSum>", text).group(1)
    zeroed = text.replace(f"<IR:ChkSum>{written}</IR:ChkSum>", "<IR:ChkSum>0</IR:ChkSum>")
    assert int(written) == zlib.crc32(zeroed.encode())


def test_writing_an_inline_plan_gives_its_elements_back():
    """Each line of the input appears in the output but the ones the plan does not keep
    (IR:Comment) and the checksum."""
    source = iredes_file().decode().split("\r\n")
    written = write_iredes(read_iredes(iredes_file()), created="2026-11-30T07:00:00")
    out = written.split("\r\n")
    # The inline fixture writes TMatrix columns on one line each; compare the rest.
    kept = [line for line in source if "IR:Col>" not in line and "ChkSum" not in line
            and "IR:Comment" not in line]
    assert [line for line in kept if line not in out] == []


def test_assignments_go_into_hole_options_and_read_back(plan):
    assignments = {"1": {"boom": "left", "order": 2, "start_s": 10.5, "end_s": 98.25},
                   "3": {"boom": "right", "order": 1}}
    text = write_iredes(plan, assignments=assignments)
    assert '<HoleOptions xmlns:kp="urn:kinoplan:drill-plan:assignment:1">' in text
    assert "<kp:Boom>left</kp:Boom>" in text and "<kp:StartS>10.5</kp:StartS>" in text
    read, found = read_iredes_with_assignments(text)
    assert read == plan
    assert found == {"1": {"boom": "left", "order": 2, "start_s": 10.5, "end_s": 98.25},
                     "3": {"boom": "right", "order": 1}}
    assert read_iredes_with_assignments(write_iredes(plan))[1] == {}


def test_assignments_are_checked(plan):
    with pytest.raises(PlanFormatError, match="no hole has the id '99'") as info:
        write_iredes(plan, assignments={"99": {"boom": "left"}})
    assert info.value.loc == ("assignments", "99")
    with pytest.raises(PlanFormatError, match="unknown field 'arm'") as info:
        write_iredes(plan, assignments={"1": {"arm": "left"}})
    assert info.value.loc == ("assignments", "1", "arm")
    with pytest.raises(PlanFormatError, match="order must be an integer"):
        write_iredes(plan, assignments={"1": {"order": 1.5}})


def test_northing_in_x_on_writing_reads_back_with_the_option(plan):
    text = write_iredes(plan, northing_in_x=True)
    assert read_iredes(text, northing_in_x=True) == plan
    assert read_iredes(text).collars()[0, 0] == plan.collars()[0, 1]


# ---- CSV -----------------------------------------------------------------------------------
CSV = """id,collar_x,collar_y,collar_z,toe_x,toe_y,toe_z,type,diameter_mm
1,512000,-3300,20300,516494,-3536,20300,Contour,45
2,512000,150,21000,516700,150,21000,Reamer,
"""


def test_reads_csv():
    plan = read_csv(CSV)
    assert plan.ids() == ["1", "2"]
    np.testing.assert_array_equal(plan.toes()[0], [516_494.0, -3_536.0, 20_300.0])
    assert plan.holes[0].diameter_mm == 45.0 and plan.holes[1].diameter_mm is None
    assert plan.holes[1].type == "Reamer"
    np.testing.assert_array_equal(plan.frame, np.eye(4))
    assert read_csv(CSV.replace(",", ";")) == plan     # a spreadsheet's semicolons
    assert read_csv(("\ufeff" + CSV).encode()) == plan  # bytes with a byte order mark


def test_csv_round_trip(plan):
    again = read_csv(to_csv(plan))
    assert again.holes == plan.holes


@pytest.mark.parametrize("text, row, column", [
    (CSV.replace("516700,150", "516700,1x0"), 3, "toe_y"),
    (CSV.replace(",Reamer,", ""), 3, "type"),                 # too few cells
    (CSV.replace("-3300,", "nan,"), 2, "collar_y"),
    (CSV.replace("Contour,45", "Contour,-45"), 2, "diameter_mm"),
    (CSV.replace("\n2,", "\n1,"), 3, "id"),                   # the id again
    (CSV.replace("toe_z", "toe_zz"), 1, "toe_zz"),            # unknown column
])
def test_a_malformed_csv_row_names_row_and_column(text, row, column):
    with pytest.raises(PlanFormatError, match=f"row {row}") as info:
        read_csv(text)
    assert info.value.loc == ("row", row, column)
    assert (info.value.row, info.value.column) == (row, column)


def test_a_zero_depth_csv_hole_names_the_hole_and_row():
    text = CSV.replace("516700,150,21000", "512000,150,21000")
    with pytest.raises(PlanFormatError, match="hole '2' has zero depth") as info:
        read_csv(text)
    assert info.value.row == 3 and info.value.hole_id == "2"


def test_csv_needs_a_header_with_the_coordinates():
    with pytest.raises(PlanFormatError, match="no column 'toe_x'") as info:
        read_csv("id,collar_x,collar_y,collar_z\n1,0,0,0\n")
    assert info.value.loc == ("row", 1, "toe_x")


# ---- JSON ----------------------------------------------------------------------------------
def test_json_round_trip(plan):
    data = json.loads(json.dumps(plan.to_json()))
    assert set(data) == {"plan_id", "name", "frame_name", "frame", "holes"}
    assert set(data["holes"][0]) == {"id", "name", "collar", "toe", "type", "diameter_mm"}
    assert read_json(data) == plan


@pytest.mark.parametrize("change, loc", [
    (lambda d: d["holes"][1]["toe"].__setitem__(2, "21"), ("holes", 1, "toe", 2)),
    (lambda d: d["holes"][1].__setitem__("toe", [1.0, 2.0]), ("holes", 1, "toe")),
    (lambda d: d["holes"][0].__setitem__("colour", "red"), ("holes", 0, "colour")),
    (lambda d: d["holes"][2].__setitem__("toe", d["holes"][2]["collar"]), ("holes", 2)),
    (lambda d: d["holes"][2].__setitem__("diameter_mm", 0), ("holes", 2, "diameter_mm")),
    (lambda d: d["frame"][3].__setitem__(3, 2.0), ("frame",)),
    (lambda d: d.__setitem__("hole_count", 4), ("hole_count",)),
    (lambda d: d.pop("plan_id"), ("plan_id",)),
])
def test_json_errors_name_the_field(plan, change, loc):
    data = plan.to_json()
    change(data)
    with pytest.raises(PlanFormatError) as info:
        read_json(data)
    assert info.value.loc == loc


def test_json_hole_count_cap():
    data = {"plan_id": "p", "holes": [{"id": str(k), "collar": [0, 0, 0], "toe": [1, 0, 0]}
                                      for k in range(MAX_HOLES + 1)]}
    with pytest.raises(PlanTooLargeError) as info:
        read_json(data)
    assert info.value.loc == ("holes",)
