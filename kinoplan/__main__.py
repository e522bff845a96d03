"""``python -m kinoplan``: start the API and the 3D viewer (unless ``--no-viewer``).

The flags are ``python -m app``'s (``app.__main__``: one per ``app.config.Settings`` field,
each falling back to ``KINOPLAN_<NAME>`` and then to the field's default). This module wires
the viewer (``web.viewer.Viewer``) into the service; ``python -m app`` runs the API alone.

``python -m kinoplan warm-up`` loads every compiled kernel of the service and of its job
kinds (``planning.warm.warm_up``), compiling those numba's cache lacks, and exits: the
Docker image runs it at build time, ``make kernels`` on a checkout.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from app.__main__ import parse_args, serve
from app.config import Settings

#: The word that selects the warm-up command instead of the service.
WARM_UP = "warm-up"

DESCRIPTION = "Start the kinoplan API and its 3D viewer (unless --no-viewer)."
EPILOG = (f"`python -m kinoplan {WARM_UP}` instead loads (or, the first time on a machine, "
          "compiles) every compiled kernel and exits; `python -m app` starts the API alone.")


def start_viewer(settings: Settings, state: Any) -> Any:
    """The 3D viewer on ``settings.host:settings.viewer_port`` for the application's
    ``state`` (an ``app.viewer.ViewerStarter``). Its port checks Origin against
    ``allowed_origins``, and the API key when one is set (``web.gate``)."""
    from web.viewer import Viewer

    return Viewer.start(settings.host, settings.viewer_port, state,
                        api_key=settings.api_key, allowed_origins=settings.allowed_origins)


def warm_up_main(argv: list[str]) -> int:
    """``python -m kinoplan warm-up``: every kernel loaded or compiled; 0 when all are
    compiled, 1 when some part runs without them (numba missing, ``KINOPLAN_JIT=0``)."""
    p = argparse.ArgumentParser(
        prog=f"python -m kinoplan {WARM_UP}",
        description="Load every compiled kernel of the service and its job kinds from "
                    "numba's cache (NUMBA_CACHE_DIR, or __pycache__ beside the sources), "
                    "compiling the ones it lacks, and print the seconds each part took.")
    from planning.warm import PARTS, warm_up

    p.add_argument("parts", nargs="*", metavar="PART",
                   help=f"only these parts ({', '.join(PARTS)}; default: all), e.g. to "
                        "compile them in two processes at once on a fresh machine")
    args = p.parse_args(argv)
    unknown = [name for name in args.parts if name not in PARTS]
    if unknown:
        p.error(f"unknown part {unknown[0]!r}; known: {', '.join(PARTS)}")
    report = warm_up(args.parts or None)
    parts = ", ".join(f"{name} {seconds:.1f} s" if report.compiled[name] else f"{name} off"
                      for name, seconds in report.seconds.items())
    print(f"compiled kernels: {parts} (total {report.total_seconds:.1f} s)")
    if not all(report.compiled.values()):
        print("kinoplan: some kernels are off (numba missing, or KINOPLAN_JIT=0): those "
              "parts take the numpy path", file=sys.stderr)
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m kinoplan [flags]`` or ``python -m kinoplan warm-up``."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == [WARM_UP]:
        return warm_up_main(argv[1:])
    settings = parse_args(argv, prog="python -m kinoplan", description=DESCRIPTION,
                          epilog=EPILOG)
    return serve(settings, start_viewer)


if __name__ == "__main__":
    sys.exit(main())
