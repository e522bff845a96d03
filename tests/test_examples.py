"""The sample files of ``examples/`` and the README's tour that uses them.

The README's shell blocks are run by bash itself, with ``curl`` replaced by a function that
records its arguments as the shell parsed them (variables, quotes and continuations
resolved); each recorded command is then sent, as curl would send it, to an in-process
application. So every curl command of the README is run, and none can drift from the
service. The few that cannot succeed here say why (``NOT_2XX``) and must answer what the
contract says they answer in that case.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import pytest
from fastapi.testclient import TestClient

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
README = ROOT / "README.md"
SAMPLES = ("glt_meshed.zip", "crate.stl", "cell_scene.json", "drill_face.csv",
           "drill_round.xml")

#: Stands for the id of the job the README's tour submits, until the service has given one.
JOB_PLACEHOLDER = "JOBID"

#: README commands that cannot answer 2xx on an application without the viewer whose jobs
#: stay queued: (method, path pattern) -> (the status the API documents, why).
NOT_2XX: dict[tuple[str, str], tuple[int, str]] = {
    ("GET", rf"/jobs/{JOB_PLACEHOLDER}/result"): (409, "the 40 s tracking job has not run"),
    ("GET", rf"/jobs/{JOB_PLACEHOLDER}/plot"): (409, "the 40 s tracking job has not run"),
    ("GET", rf"/jobs/{JOB_PLACEHOLDER}/trajectory(\?.*)?"): (409, "the tracking job has not run"),
    ("POST", r"/viewer/show"): (503, "the viewer is not started here (tests/web covers it)"),
}

#: A ``curl`` that records its argv (NUL-separated, one record per line of \x1e) and answers
#: what the README's ``JOB=$(curl ... | python3 ...)`` reads.
FAKE_CURL = r"""
curl() {
  printf '%s\0' "$@" >> "$CURL_LOG"
  printf '\036' >> "$CURL_LOG"
  printf '{"id": "JOBID"}'
}
"""


def shell_blocks(text: str) -> list[str]:
    """The ```sh / ```bash blocks of a Markdown text that run curl."""
    blocks = re.findall(r"```(?:sh|bash)\n(.*?)```", text, flags=re.S)
    return [b for b in blocks if re.search(r"(^|[\s$(])curl ", b)]


def curl_count(block: str) -> int:
    """How many curl commands a shell block runs (code only, comments left out)."""
    n = 0
    for line in block.splitlines():
        code = line.split(" #")[0] if not line.lstrip().startswith("#") else ""
        n += len(re.findall(r"(?:^|[\s$(])curl ", code))
    return n


def record_readme_curls(workdir: Path) -> list[list[str]]:
    """Run the README's curl blocks in bash (the service start left out) and return each
    curl's arguments."""
    script = FAKE_CURL
    for block in shell_blocks(README.read_text()):
        kept = [line for line in block.splitlines()
                if not re.match(r"\s*\.venv/bin/python -m kinoplan\b", line)]
        script += "\n".join(kept) + "\n"
    bindir = workdir / "bin"
    bindir.mkdir()
    (bindir / "python3").symlink_to(sys.executable)
    (workdir / "examples").symlink_to(EXAMPLES)
    log = workdir / "curl.log"
    env = {**os.environ, "CURL_LOG": str(log), "PATH": f"{bindir}:{os.environ['PATH']}"}
    done = subprocess.run(["bash", "-c", script], cwd=workdir, env=env, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    records = log.read_bytes().decode().split("\x1e")[:-1]
    return [r.split("\0")[:-1] for r in records]


def to_request(argv: list[str], workdir: Path) -> dict:
    """What curl sends for ``argv``: method, path (with query), headers, body or form."""
    method, url, headers, body, form = None, None, {}, None, []
    args = iter(argv)
    for a in args:
        if a in ("-s", "-sf", "-f", "-i", "-si"):
            continue
        if a == "-X":
            method = next(args)
        elif a.startswith("-X"):
            method = a[2:]
        elif a == "-H":
            name, _, value = next(args).partition(":")
            headers[name.strip().lower()] = value.strip()
        elif a == "-d":
            data = next(args)
            if data.startswith("@"):  # curl -d @file drops the file's line breaks
                data = (workdir / data[1:]).read_text().replace("\r", "").replace("\n", "")
            body = data
        elif a == "--data-binary":  # @file: its bytes as they are
            data = next(args)
            body = ((workdir / data[1:]).read_bytes().decode("utf-8") if data.startswith("@")
                    else data)
        elif a == "-F":
            form.append(next(args))
        elif a == "-o":
            next(args)
        else:
            assert not a.startswith("-"), f"a curl option the test does not know: {a}"
            url = a
    parts = urlsplit(url)
    path = parts.path + (f"?{parts.query}" if parts.query else "")
    method = method or ("POST" if body is not None or form else "GET")
    files, fields = {}, {}
    for item in form:
        key, _, value = item.partition("=")
        if value.startswith("@"):
            file = workdir / value[1:]
            files[key] = (file.name, file.read_bytes())
        else:
            fields[key] = value
    return {"method": method, "path": path, "headers": headers, "body": body,
            "files": files, "data": fields}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[list[list[str]], Path]:
    """The README's curl commands as bash parsed them, and the folder they ran in."""
    if shutil.which("bash") is None:
        pytest.skip("needs bash")
    workdir = tmp_path_factory.mktemp("readme")
    return record_readme_curls(workdir), workdir


def test_every_readme_curl_is_recorded(recorded):
    """The recorder saw each curl of the README (a block it failed to run would hide some)."""
    commands, _ = recorded
    expected = sum(curl_count(b) for b in shell_blocks(README.read_text()))
    assert expected >= 15 and len(commands) == expected
    paths = [urlsplit(next(a for a in c if a.startswith("http"))).path for c in commands]
    assert "/robots/import" in paths and "/meshes" in paths and "/scenes" in paths
    used = " ".join(" ".join(c) for c in commands)
    for name in SAMPLES[:3]:
        assert f"@examples/{name}" in used
    assert "@holes.json" in used  # made from examples/drill_face.csv by the README's python3


def test_not_2xx_exceptions_are_still_in_the_readme(recorded, tmp_path):
    """Every exception names a command the README still has."""
    commands, workdir = recorded
    requests = [to_request(c, workdir) for c in commands]
    for method, pattern in NOT_2XX:
        assert any(r["method"] == method and re.fullmatch(pattern, r["path"])
                   for r in requests), (method, pattern)


@pytest.fixture(scope="module")
def readme_client(tmp_path_factory) -> Iterator[TestClient]:
    """An application without the viewer; not entered, so its jobs stay queued."""
    from app.config import Settings
    from app.main import create_app

    data_dir = tmp_path_factory.mktemp("readme_app")
    api = create_app(Settings(no_viewer=True, data_dir=data_dir, workers=1,
                              prebuild_collision=False))
    yield TestClient(api)
    api.state.compute.shutdown()


@pytest.mark.slow
def test_readme_tour_answers_as_documented(recorded, readme_client, motion_kernels):
    """Each curl of the README, sent as curl sends it, answers 2xx (the exceptions: their
    documented status); the imported robot plans its move, every hole is reached."""
    commands, workdir = recorded
    job_id = None
    answers = {}
    for argv in commands:
        req = to_request(argv, workdir)
        path, body = req["path"], req["body"]
        expected = next((s for (m, p), (s, _) in NOT_2XX.items()
                         if m == req["method"] and re.fullmatch(p, path)), None)
        if job_id is not None:
            path = path.replace(JOB_PLACEHOLDER, job_id)
            body = body.replace(JOB_PLACEHOLDER, job_id) if body else body
        r = readme_client.request(req["method"], path, headers=req["headers"],
                                  content=body.encode() if body is not None else None,
                                  files=req["files"] or None, data=req["data"] or None)
        if expected is None:
            assert 200 <= r.status_code < 300, (argv, r.status_code, r.text[:500])
        else:
            assert r.status_code == expected, (argv, r.status_code, r.text[:500])
        if req["method"] == "POST" and path == "/jobs":
            job_id = r.json()["id"]
        answers[(req["method"], path.split("?")[0])] = r
    assert answers[("POST", "/robots/import")].status_code == 201
    assert answers[("POST", "/meshes")].json()["triangles"] == 60
    motion = answers[("POST", "/robots/glt_meshed/motion")].json()
    assert motion["status"] == "ok" and motion["min_clearance"] > 0, motion["message"]
    results = answers[("POST", "/robots/tunnel_jumbo-middle/drill-ik")].json()["results"]
    assert len(results) == 22 and all(h["success"] for h in results)


@pytest.mark.slow
def test_meshed_robot_links_touch_only_in_some_configurations(readme_client, recorded):
    """Gaps at the joints: the arm is free at zero and at the tour's start, and no pair of
    its links collides in every configuration (a pair always in contact would make every
    plan fail)."""
    client = readme_client
    if client.get("/robots/glt_meshed").status_code == 404:
        zip_bytes = (EXAMPLES / "glt_meshed.zip").read_bytes()
        r = client.post("/robots/import", files={"file": ("glt_meshed.zip", zip_bytes)},
                        data={"id": "glt_meshed"})
        assert r.status_code == 201, r.text
    model = client.get("/robots/glt_meshed").json()
    lower = np.array([j["lower"] for j in model["joints"]])
    upper = np.array([j["upper"] for j in model["joints"]])
    q = np.random.default_rng(7).uniform(lower, upper, (300, len(lower)))
    q = np.vstack([np.zeros(len(lower)), [-1.2, 0.3, -0.3, 0, 0.5, 0], q])
    r = client.post("/robots/glt_meshed/collision", json={"q": q.tolist(), "self": True})
    assert r.status_code == 200, r.text
    results = r.json()["results"]
    assert not results[0]["collides"] and results[0]["distance"] > 20.0
    assert not results[1]["collides"]
    colliding = [x for x in results[2:] if x["collides"]]
    assert 0 < len(colliding) < 0.5 * len(results[2:])   # it can collide, but mostly not
    always = set.intersection(*({(p["link"], p["object"]) for p in x["pairs"]}
                                for x in colliding))
    assert not always


def test_sample_files_are_what_make_examples_writes(tmp_path):
    """``examples/make_examples.py`` writes the committed files byte for byte (so they are
    up to date and reproducible), each under 300 kB."""
    pytest.importorskip("trimesh")
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_examples",
                                                  EXAMPLES / "make_examples.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(tmp_path)
    for name in SAMPLES:
        committed = (EXAMPLES / name).read_bytes()
        assert (tmp_path / name).read_bytes() == committed, name
        assert len(committed) < 300_000


def test_sample_files_read_back():
    """The archive holds a URDF whose meshes are all in it; the scene is a POST /scenes body
    using the crate mesh; the drill plan has 22 holes drilled along +x."""
    import csv
    import zipfile

    with zipfile.ZipFile(EXAMPLES / "glt_meshed.zip") as z:
        names = set(z.namelist())
        urdf = z.read("glt_meshed/urdf/glt_meshed.urdf").decode()
    meshes = set(re.findall(r'filename="package://([^"]+)"', urdf))
    assert meshes and meshes <= names and len(meshes) == 5
    scene = json.loads((EXAMPLES / "cell_scene.json").read_text())
    assert scene["id"] == "cell"
    assert [o["type"] for o in scene["objects"]] == ["box", "mesh", "points"]
    assert scene["objects"][1]["mesh"] == "crate"
    with open(EXAMPLES / "drill_face.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 22 and len({r["id"] for r in rows}) == 22
    for r in rows:
        collar = np.array([float(r[f"collar_{a}"]) for a in "xyz"])
        toe = np.array([float(r[f"toe_{a}"]) for a in "xyz"])
        np.testing.assert_allclose(toe - collar, [3200.0, 0.0, 0.0])
        assert r["type"] in ("contour", "lifter", "cut") and float(r["diameter_mm"]) > 0
    # The IREDES file is the same face: its checksum is the CRC32 of its bytes with 0 in
    # its place (computed here), its holes the CSV's converted to metres.
    import zlib

    xml = (EXAMPLES / "drill_round.xml").read_bytes()
    (chk,) = re.findall(rb"<IR:ChkSum>(\d+)</IR:ChkSum>", xml)
    assert zlib.crc32(xml.replace(b"<IR:ChkSum>" + chk, b"<IR:ChkSum>0")) == int(chk)
    holes = re.findall(rb"<Hole>.*?</Hole>", xml, re.S)
    assert len(holes) == 22
    for hole, r in zip(holes, rows, strict=True):
        (start,) = re.findall(rb"<StartPoint>(.*?)</StartPoint>", hole, re.S)
        xyz = [float(re.search(b"<IR:Point" + a + rb">([-\d.]+)<", start)[1])
               for a in (b"X", b"Y", b"Z")]
        np.testing.assert_allclose(np.array(xyz) * 1000.0,
                                   [float(r[f"collar_{a}"]) for a in "xyz"], atol=1e-6)


#: A file a curl command sends: ``-d @file``, ``--data-binary @file``, ``-F name=@file``.
SENT_FILE = re.compile(r"(?:-d|--data(?:-binary)?|-F\s+[\w-]+=)\s*@([\w./-]+)")


def test_every_file_a_doc_sends_is_a_sample_or_made_before():
    """A curl example of the README or docs/ sends only a file of ``examples/`` or one its
    own block made earlier (``> file``, ``zip ... file``), so a reader can run it as it is."""
    pages = [README, *sorted((ROOT / "docs").glob("*.md"))]
    checked = 0
    for page in pages:
        for block in shell_blocks(page.read_text()):
            for m in SENT_FILE.finditer(block):
                name = m.group(1)
                made_before = name in block[:m.start()]
                assert name.startswith("examples/") or made_before, (page.name, name)
                checked += 1
    assert checked >= 8


def test_docs_name_only_sample_files_that_exist():
    """Every ``examples/...`` file the README and docs/ name is there."""
    texts = [README.read_text(), *(p.read_text() for p in (ROOT / "docs").glob("*.md"))]
    named = {m for t in texts for m in re.findall(r"examples/([\w.-]+\.\w+)", t)}
    assert set(SAMPLES) <= named
    for name in named:
        assert (EXAMPLES / name).is_file(), name
