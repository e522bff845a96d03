"""Text that comes from requests, shown in the viewer's panel as the characters it is.

The panel's texts are Markdown: the browser renders them with GitHub's extensions and raw
HTML, unsanitised (viser), and viser's server replaces ``![alt](path)`` by the image file at
``path`` on its own disk, embedded. Names and messages sent here would be a tag, an image
(one of them a file of the server's), a link, an autolink or a way out of a code span; the
Markdown the viewer then holds is read as CommonMark reads it (``read``): none of their
markup is live, nothing is embedded, and the text reads as it was sent.
"""

from __future__ import annotations

import re
import string

import numpy as np
import pytest
from fastapi.testclient import TestClient

from kinematics.library import builtin_model
from web.text import code, plain
from web.viewer import Viewer

ROBOT = "glt_palletizer"
WORD_JOINER = "\u2060"
#: What remark-gfm turns into links without any markup: URLs, "www." and e-mail addresses.
GFM_AUTOLINK = re.compile(r"(?i)https?://|www\.|[-.\w+]+@[-\w]+(\.[-\w]+)+")
#: Markup a sender could use for tags, entities, images and links.
MARKS = ("<", "&", "[", "]")

HOSTILE = [
    "<img src=x onerror=alert(1)>",
    "<script>alert(1)</script>",
    "![pixel](https://evil.example/p.png)",
    "[click](https://evil.example/phish 'title')",
    "<https://evil.example>",
    "www.evil.example and ops@evil.example",
    "&lt;b&gt; &amp; &#60;i&#62;",
    "**bold** _em_ ~~gone~~ `tick` ``two``",
    "x` <img src=y> `",
    "a\n\n# heading\n- item\n\n    code",
    "| cell | cell |",
    "{alert(1)} \\ \\* trailing\\",
]



def read(markdown: str) -> tuple[str, str, str]:
    """``(live, shown, text)``: Markdown inline text as CommonMark reads it. ``live`` keeps
    what may still be markup (every backslash-escaped character and every code span's
    content blanked out), ``shown`` the text a reader sees (escapes and code fences read),
    ``text`` what of it lies outside code spans (where GitHub's autolinks are found)."""
    live, shown, text, i = [], [], [], 0
    while i < len(markdown):
        c = markdown[i]
        if c == "\\" and markdown[i + 1:i + 2] in set(string.punctuation):
            live.append(" ")
            shown.append(markdown[i + 1])
            text.append(markdown[i + 1])
            i += 2
            continue
        if c == "`":
            run = len(markdown[i:]) - len(markdown[i:].lstrip("`"))
            end = re.compile(rf"(?<!`){'`' * run}(?!`)").search(markdown, i + run)
            if end is not None:
                body = markdown[i + run:end.start()].replace("\n", " ")
                if len(body) > 2 and body[0] == body[-1] == " " and body.strip():
                    body = body[1:-1]
                live.append(" ")
                shown.append(body)
                text.append(" ")
                i = end.end()
                continue
            live.append(c * run)
            shown.append(c * run)
            text.append(c * run)
            i += run
            continue
        live.append(c)
        shown.append(c)
        text.append(c)
        i += 1
    return "".join(live), "".join(shown), "".join(text)


def one_line(text: str) -> str:
    return " ".join(text.split())


def assert_inert(markdown: str, *sent: str) -> None:
    """No markup of ``sent`` is live in ``markdown``, and each reads as sent (on one line)."""
    live, shown, text = read(markdown)
    for mark in MARKS:
        assert mark not in live, (mark, markdown)
    assert "\n#" not in live and "\n    " not in live, markdown
    assert not GFM_AUTOLINK.search(text), text
    readable = shown.replace(WORD_JOINER, "")
    for text in sent:
        assert one_line(text) in readable, (text, readable)


def assert_panel_inert(handle, *sent: str) -> None:
    """A markdown element of the panel: inert, and sent to browsers as it is (viser embedded
    no image into it)."""
    assert_inert(handle.content, *sent)
    assert handle._markdown == handle.content


# ---- the helpers ----------------------------------------------------------------------------
@pytest.mark.parametrize("text", HOSTILE)
def test_plain_and_code_show_any_text_literally(text):
    assert_inert(f"- before {plain(text)} after", text)
    assert_inert(f"**Motion** of {code(text)} (job {code('j1')})", text, "j1")
    assert_inert(f"| {plain(text)} | x |", text)


def test_ordinary_text_reads_as_it_did():
    assert plain("rrt connect") == "rrt connect"
    assert code("glt_palletizer") == "`glt_palletizer`"
    assert plain("goal in collision, 1.5 mm") == r"goal in collision\, 1\.5 mm"
    assert read(plain("goal in collision, 1.5 mm"))[1] == "goal in collision, 1.5 mm"
    assert read(code("a `b` c"))[1] == "a `b` c"
    assert code("") == "``"  # as before: an empty span


# ---- what the viewer shows ------------------------------------------------------------------
def test_a_motion_answer_shows_its_planner_message_and_object_names_as_text(api, tmp_path):
    """The answer of ``POST /robots/{id}/motion`` as a client may send it back: its planner,
    message and colliding objects' names are the sender's text."""
    import imageio.v3 as iio

    secret = tmp_path / "secret.png"  # a file of the server's that an image would embed
    iio.imwrite(secret, np.full((4, 4, 3), 200, dtype=np.uint8))
    planner = f"<img src=x onerror=alert(1)> ![secret]({secret}) rrt_connect"
    message = ("[click](https://evil.example/phish) *look* <script>alert(1)</script>\n\n"
               "# www.evil.example ops@evil.example")
    pairs = [["box` <img src=y> `", "![p](https://evil.example/p.png)"]]
    names = [j.name for j in builtin_model(ROBOT).joints]
    answer = {"robot": ROBOT, "joints": names, "status": "start_in_collision",
              "message": message, "path": [], "pairs": pairs, "planner": planner}
    r = TestClient(api).post("/viewer/show", json={"motion": answer})
    assert r.status_code == 200, r.text
    plan = api.state.viewer.gui.plan
    assert_panel_inert(plan, planner, message, *pairs[0])
    assert "data:" not in plan._markdown
    # The rest of the summary is still Markdown: bold status, the robot in code.
    assert "**start\\_in\\_collision**" in plan.content and "`glt_palletizer`" in plan.content


def test_a_custom_robots_cylinder_and_joint_names_show_as_text(api):
    data = builtin_model("pile_driver").to_dict()
    data["id"] = "odd_pile"
    joint = "<img src=x onerror=alert(1)> | boom"
    cylinder = "![c](https://evil.example/c.png) [x](https://evil.example)"
    data["joints"][1]["name"] = joint
    data["cylinders"][0].update(name=cylinder, joint=joint)
    client = TestClient(api)
    r = client.post("/robots", json=data)
    assert r.status_code == 201, r.text
    r = client.post("/viewer/show", json={"robot": "odd_pile"})
    assert r.status_code == 200, r.text
    v: Viewer = api.state.viewer
    table = v.gui.cylinders
    assert_panel_inert(table, joint, cylinder)
    rows = [line for line in table.content.splitlines() if line.startswith("| ")]
    # Still a table of five columns (escaped pipes split no cell), one row per cylinder.
    assert len(rows) == 1 + len(v._arms[""].nodes.drawing.cylinders)
    assert all(len(re.findall(r"(?<!\\)\|", row)) == 5 for row in rows)  # four columns


def test_a_failed_jobs_error_shows_as_text_in_the_workspace_panel(api):
    v: Viewer = api.state.viewer
    error = "ValueError: <img src=x onerror=alert(1)> see [docs](https://evil.example)"
    store = api.state.store
    store.add_job("w1", "workspace", {"robot": ROBOT, "samples": 1000}, {})
    store.finish_job("w1", "failed", error=error)
    v._workspace_job = "w1"
    v._poll_workspace()
    assert_panel_inert(v.gui.workspace, error, "w1")
    assert "failed" in v.gui.workspace.content


def test_the_cylinder_table_keeps_stroke_and_travel_apart():
    """The stroke (the current extension, as the API says) and the full travel in one cell
    with a separator: never two numbers run together ("121.3231.4")."""
    from web.gui import cylinder_table
    from web.scene import CylinderDrawing

    c = CylinderDrawing(name="boom", joint="boom", barrel_pin=np.zeros(3), rod_pin=np.ones(3),
                        length=489.99, min_length=368.71, max_length=600.07, within_stroke=True)
    header, _, row = cylinder_table([c]).split("\n")
    assert "stroke / travel mm" in header
    assert row.split("|")[4].strip() == "121.3 / 231.4"
