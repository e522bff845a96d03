"""The replay page of a real motion job in a real browser: headless Chromium (Debian's, not
Playwright's download) driven by Playwright, the page opened from disk (``file://``) with the
network off and every http(s) request aborted and counted.

The page's test hook ``window.__replay`` says what it holds (node names, frames) and where
it is (time, frame, playing); the canvas is read back from a screenshot.
"""

from __future__ import annotations

import io
import json
import re
import shutil
import time

import numpy as np
import pytest
from chromium_setup import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app

sync_api = pytest.importorskip("playwright.sync_api",
                               reason="Playwright is in the 'test' extra: pip install -e '.[test]'")

pytestmark = pytest.mark.browser

GLT = "glt_palletizer"
MOTION = {"robot": GLT, "start": [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0],
          "goal": {"q": [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]}, "planner": "rrt_connect",
          "time_limit": 10,
          "scene": {"objects": [{"type": "box", "id": "pallet", "size": [400, 400, 300],
                                 "pose": [[1, 0, 0, 900], [0, 1, 0, 0], [0, 0, 1, 150],
                                          [0, 0, 0, 1]]}]}}
#: Least standard deviation (0..255) of the canvas's grey levels: a blank canvas has 0.
MIN_PIXEL_STD = 4.0


@pytest.fixture(scope="module")
def replay_file(tmp_path_factory):
    """The replay page of a succeeded motion job of the palletizer, written to a file, and
    the number of samples of its trajectory."""
    if not shutil.which(CHROMIUM):
        pytest.fail(f"Chromium not found at {CHROMIUM}: run `make chromium` "
                    "(apt-get install -y chromium)")
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("data"),
                              workers=1))
    with TestClient(api) as client:
        r = client.post("/jobs", json={"kind": "motion", "params": MOTION})
        assert r.status_code == 202, r.text
        job_id = r.json()["id"]
        end = time.monotonic() + 120
        while (job := client.get(f"/jobs/{job_id}").json())["status"] not in (
                "succeeded", "failed", "cancelled"):
            assert time.monotonic() < end, "the motion job did not finish"
            time.sleep(0.1)
        assert job["status"] == "succeeded", job
        samples = len(client.get(f"/jobs/{job_id}/result").json()["trajectory"]["t"])
        page = client.get(f"/jobs/{job_id}/replay.html")
        assert page.status_code == 200
    path = tmp_path_factory.mktemp("replay") / "replay.html"
    path.write_text(page.text, encoding="utf-8")
    return path, samples


@pytest.fixture(scope="module")
def browser(replay_file):
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def _pixel_std(png: bytes) -> float:
    from PIL import Image

    grey = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=np.float64)
    return float(grey.std())


def test_the_replay_plays_offline_from_disk(replay_file, browser):
    path, samples = replay_file
    context = browser.new_context(viewport={"width": 900, "height": 600})
    context.set_offline(True)
    requested: list[str] = []

    def refuse(route):
        requested.append(route.request.url)
        route.abort()

    context.route(re.compile(r"^https?://"), refuse)
    errors: list[str] = []
    page = context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(path.as_uri())
    page.wait_for_function("() => window.__replay && window.__replay.renders > 0")
    hook = page.evaluate("() => JSON.parse(JSON.stringify({frames: __replay.frames, "
                         "nodes: __replay.nodes, links: __replay.links, time: __replay.time,"
                         " duration: __replay.duration, drawn: __replay.drawn}))")
    assert hook["frames"] == samples
    names = set(hook["nodes"])
    assert {f"{GLT}/base", f"{GLT}/tool/x", "scene/pallet"} <= names
    assert {f"{GLT}/link_{i}" for i in range(6)} <= names
    assert hook["time"] == 0 and hook["duration"] > 0 and hook["drawn"] > 100

    canvas = page.locator("#view")
    assert _pixel_std(canvas.screenshot()) > MIN_PIXEL_STD

    # Play: the time and the frame advance, the picture changes
    before = canvas.screenshot()
    page.get_by_role("button", name="Play").click()
    page.wait_for_function("() => window.__replay.time > 0.2 * window.__replay.duration")
    state = page.evaluate("() => [window.__replay.frame, window.__replay.playing]")
    assert state[0] > 0 and state[1] is True
    page.get_by_role("button", name="Pause").click()
    paused = page.evaluate("() => window.__replay.time")
    page.wait_for_timeout(300)
    assert page.evaluate("() => window.__replay.time") == paused
    assert canvas.screenshot() != before

    # The slider jumps to the end; orbit and zoom redraw
    page.evaluate("""() => { const s = document.getElementById('time');
        s.value = s.max; s.dispatchEvent(new Event('input')); }""")
    assert page.evaluate("() => window.__replay.frame") == samples - 1
    yaw = page.evaluate("() => window.__replay.camera.yaw")
    box = canvas.bounding_box()
    page.mouse.move(box["x"] + 300, box["y"] + 300)
    page.mouse.down()
    page.mouse.move(box["x"] + 420, box["y"] + 320, steps=4)
    page.mouse.up()
    assert page.evaluate("() => window.__replay.camera.yaw") != yaw
    dist = page.evaluate("() => window.__replay.camera.dist")
    page.mouse.wheel(0, 400)
    page.wait_for_function(f"() => window.__replay.camera.dist > {json.dumps(dist)}")
    assert _pixel_std(canvas.screenshot()) > MIN_PIXEL_STD

    assert requested == [] and errors == []
    context.close()
