"""Every job kind of the service, in one place.

Importing this module imports, by name, each module that defines kinds; each of them
registers its kinds with ``app.jobs.kinds.register`` when imported (a name registered twice
is an error). The service, its workers (the local pool's forkserver preloads this module; a
Dask worker imports it with the job function) and the viewer read ``KINDS`` from here, so
they all see the same kinds.

Hooks: a kind's ``plot`` is set where the kind is defined (``GET /jobs/{id}/plot`` serves the
kinds that have one), as are the submission hooks the job manager calls for any kind
(``prepare``, ``check``, ``needs_geometry``, ``keep_latest``: ``app.jobs.kinds.JobKind``); the
viewer's drawings are registered per kind name in ``web.results``, which checks at import
that each names a kind listed here.

A new kind: define ``Params``, ``Result`` and ``run`` in a module, ``register`` them there,
and import the module below.
"""

from __future__ import annotations  # noqa: I001 - the kinds import in listing order

# The order of these imports is the order kinds register in, which GET /jobs/kinds and the
# OpenAPI document list them in: kept as it is, for the clients that read it.
from . import kinds
from . import model_kinds
from . import drilling_kinds
from . import motion_kinds
from . import path_kinds
from . import tracking_kinds
from . import round_kinds
from . import pallet_kinds
from . import pile_kinds
from .kinds import KINDS, JobKind, get_kind

__all__ = ["KINDS", "JobKind", "get_kind", "KIND_MODULES"]

#: The modules that define kinds.
KIND_MODULES = (kinds, model_kinds, path_kinds, tracking_kinds, drilling_kinds, motion_kinds,
                round_kinds, pallet_kinds, pile_kinds)
