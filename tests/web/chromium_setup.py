"""How the browser tests start Debian's Chromium (not Playwright's download): where it is,
its flags (no sandbox as root, software rendering, nothing fetched in the background) and
how long a page may take to show what a test waits for."""

from __future__ import annotations

import shutil

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-quic",
                 "--no-first-run"]
TIMEOUT_MS = 20_000
