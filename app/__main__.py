"""``python -m app``: start the API alone, without the 3D viewer.

``python -m kinoplan`` starts the API and the 3D viewer (the viewer sits above the service and
``app`` never imports it): it parses the same flags with ``parse_args`` and serves with
``serve``, handing it the viewer to start. Here ``--viewer-port``, ``--no-viewer`` and
``--allowed-origins`` are accepted and have no effect.

The flags are ``app.config.Settings``'s fields, one each (``data_dir`` -> ``--data-dir``,
its help the field's description). Every flag falls back to the environment variable
``KINOPLAN_<NAME>`` and then to the field's default.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import types
import typing
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from pydantic.fields import FieldInfo

from .config import Settings
from .viewer import ViewerStarter

log = logging.getLogger("kinoplan")


def flag_name(field: str) -> str:
    """``data_dir`` -> ``--data-dir``."""
    return "--" + field.replace("_", "-")


def _value_type(annotation: Any) -> Any:
    """The annotation without ``None`` (``str | None`` -> ``str``)."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return annotation


def _add_flag(p: argparse.ArgumentParser, name: str, info: FieldInfo, current: Any) -> None:
    """One flag for the field ``name``, its default the value ``current`` that the
    environment (or the field's default) gives."""
    help_text = (info.description or name).replace("%", "%%")
    env = f"KINOPLAN_{name.upper()}"
    if current is None:
        default = "unset"
    else:  # repr=False marks a secret: its value is never printed
        default = "%(default)s" if info.repr else "set"
    kind = _value_type(info.annotation)
    if kind is bool:
        # On by default: --name / --no-name; off by default: --name alone.
        action = argparse.BooleanOptionalAction if current else "store_true"
        p.add_argument(flag_name(name), action=action, default=current,
                       help=f"{help_text} (env {env}; default {default})")
        return
    kwargs: dict[str, Any] = {}
    if typing.get_origin(kind) is typing.Literal:
        kwargs["choices"] = list(typing.get_args(kind))
    elif kind in (int, float, str, Path):
        kwargs["type"] = kind
    else:  # lists, dicts, ...: JSON, as pydantic-settings reads them from the environment
        kwargs["type"] = json.loads
    p.add_argument(flag_name(name), default=current, metavar=name.upper(),
                   help=f"{help_text} (env {env}; default {default})", **kwargs)


#: What ``python -m app --help`` says it does.
DESCRIPTION = ("Start the kinoplan API alone, without the 3D viewer: `python -m kinoplan` "
               "starts both. --viewer-port, --no-viewer and --allowed-origins have no effect "
               "here.")


def build_parser(env: Settings | None = None, *, prog: str = "python -m app",
                 description: str = DESCRIPTION, epilog: str | None = None,
                 ) -> argparse.ArgumentParser:
    """The argument parser: one flag per ``Settings`` field, defaults from ``env`` (by
    default the settings the environment gives). ``prog``, ``description`` and ``epilog``
    are what ``--help`` prints (``python -m kinoplan`` passes its own)."""
    env = Settings() if env is None else env
    p = argparse.ArgumentParser(prog=prog, description=description, epilog=epilog)
    for name, info in Settings.model_fields.items():
        _add_flag(p, name, info, getattr(env, name))
    return p


def parse_args(argv: list[str] | None = None, *, prog: str = "python -m app",
               description: str = DESCRIPTION, epilog: str | None = None) -> Settings:
    """Settings from the command line over the environment over the defaults; a value a
    field rejects (e.g. ``--port 0``) is a usage error naming its flag. ``prog``,
    ``description`` and ``epilog`` as ``build_parser``."""
    try:
        env = Settings()
    except ValidationError as exc:  # a bad KINOPLAN_* variable: name it, no traceback
        err = exc.errors()[0]
        name = f"KINOPLAN_{str(err['loc'][0]).upper()}" if err["loc"] else "KINOPLAN_*"
        print(f"{prog}: error: {name}: {err['msg']}", file=sys.stderr)
        raise SystemExit(2) from None
    p = build_parser(env, prog=prog, description=description, epilog=epilog)
    args = vars(p.parse_args(argv))
    try:
        return Settings(**args)
    except ValidationError as exc:
        err = exc.errors()[0]
        field = str(err["loc"][0]) if err["loc"] else ""
        p.error(f"{flag_name(field)}: {err['msg']}")
        raise  # p.error exits; keeps type checkers content


def serve(settings: Settings, start_viewer: ViewerStarter | None = None) -> int:
    """Serve the API with ``settings`` until stopped; the exit status (1: the store cannot
    be opened). ``start_viewer`` (``python -m kinoplan`` hands ``web``'s) starts the 3D
    viewer beside it, in this process, unless ``settings.no_viewer``; without it the API
    runs alone and ``POST /viewer/show`` answers 503."""
    import uvicorn

    from .main import create_app
    from .server import guarded_protocol
    from .store import StoreError

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        api = create_app(settings)
    except StoreError as exc:  # one line an operator can act on, not a traceback
        print(f"kinoplan: {exc}", file=sys.stderr)
        return 1
    if start_viewer is not None and not settings.no_viewer:
        # Same process as the API: the viewer sees the same robots and jobs (app.state).
        api.state.viewer = start_viewer(settings, api.state)
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


def main(argv: list[str] | None = None) -> int:
    """``python -m app``: the API alone (``kinoplan.__main__.main`` adds the viewer)."""
    return serve(parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
