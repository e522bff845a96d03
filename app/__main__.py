"""``python -m app``: start the API (and the 3D viewer unless ``--no-viewer``).

Every flag falls back to the environment variable ``KINOPLAN_<NAME>`` and then to the
defaults of ``app.config.Settings``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from .config import Settings

log = logging.getLogger("kinoplan")


def parse_args(argv: list[str] | None = None) -> Settings:
    env = Settings()
    p = argparse.ArgumentParser(prog="python -m app", description=__doc__.splitlines()[0])
    p.add_argument("--host", default=env.host, help="API bind address (default %(default)s)")
    p.add_argument("--port", type=int, default=env.port, help="API port (default %(default)s)")
    p.add_argument("--viewer-port", type=int, default=env.viewer_port,
                   help="3D viewer port (default %(default)s)")
    p.add_argument("--no-viewer", action="store_true", default=env.no_viewer,
                   help="do not start the 3D viewer")
    p.add_argument("--data-dir", type=Path, default=env.data_dir,
                   help="directory of the SQLite store of custom robots and jobs "
                   "(default %(default)s)")
    p.add_argument("--workers", type=int, default=env.workers,
                   help="job pool size (default: number of cores, %(default)s)")
    p.add_argument("--jobs-backend", default=env.jobs_backend,
                   help="'local' or 'dask://HOST:PORT' (default %(default)s)")
    p.add_argument("--job-time-limit-s", type=float, default=env.job_time_limit_s,
                   help="seconds a job may run, and the most one may ask for "
                   "(default %(default)s)")
    p.add_argument("--allowed-hosts", default=env.allowed_hosts,
                   help="comma-separated Host names the API answers ('*' = any; default: the "
                   "loopback names when bound to loopback, any otherwise)")
    p.add_argument("--allowed-origins", default=env.allowed_origins,
                   help="comma-separated origins of the pages that may open the 3D viewer "
                   "(default: the viewer's own addresses)")
    args = p.parse_args(argv)
    return Settings(**{**env.model_dump(), **vars(args)})


def main(argv: list[str] | None = None) -> int:
    import uvicorn

    from .main import create_app
    from .server import guarded_protocol
    from .store import StoreError

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    settings = parse_args(argv)
    try:
        api = create_app(settings)
    except StoreError as exc:  # one line an operator can act on, not a traceback
        print(f"kinoplan: {exc}", file=sys.stderr)
        return 1
    if not settings.no_viewer:
        from web.viewer import Viewer

        # Same process as the API: the viewer sees the same robots and jobs (app.state).
        # Its port checks Origin, and the API key when one is set (web.gate).
        api.state.viewer = Viewer.start(settings.host, settings.viewer_port, api.state,
                                        api_key=settings.api_key,
                                        allowed_origins=settings.allowed_origins)
        log.info("3D viewer on http://%s:%d%s", settings.host, api.state.viewer.port,
                 "/?key=<API key>" if settings.api_key else "")
    try:
        uvicorn.run(api, host=settings.host, port=settings.port, log_level="info",
                    http=guarded_protocol(settings.header_timeout_s, settings.idle_timeout_s),
                    limit_concurrency=settings.max_connections)
    finally:
        if api.state.viewer is not None:
            api.state.viewer.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
