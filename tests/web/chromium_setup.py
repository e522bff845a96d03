"""How the browser tests start Debian's Chromium (not Playwright's download): where it is,
its flags (no sandbox as root, software rendering, nothing fetched in the background) and
how long a page may take to show what a test waits for."""

from __future__ import annotations

import contextlib
import shutil

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-quic",
                 "--no-first-run"]
TIMEOUT_MS = 20_000


@contextlib.contextmanager
def served_viewer(data_dir, **viewer_options):
    """The API with its job and compute workers (one each), and the viewer on a free port
    (``web.viewer.Viewer.start`` with ``viewer_options``): yields ``(app, client)``. Fails
    (does not skip) without Chromium: `make test` installs it."""
    import pytest
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app
    from web.viewer import Viewer

    if not shutil.which(CHROMIUM):
        pytest.fail(f"Chromium not found at {CHROMIUM}: run `make chromium` "
                    "(apt-get install -y chromium)")
    api = create_app(Settings(no_viewer=True, data_dir=data_dir, workers=1))
    api.state.viewer = Viewer.start("127.0.0.1", 0, api.state, environment_map=False,
                                    **viewer_options)
    try:
        with TestClient(api) as client:
            yield api, client
    finally:
        api.state.viewer.stop()
