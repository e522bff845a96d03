"""kinoplan, the product: the REST API (``app``) and the 3D viewer (``web``) started together.

``python -m kinoplan`` (or the ``kinoplan`` command) serves both; ``python -m kinoplan
warm-up`` loads, or compiles, every compiled kernel and exits. This package is the only
place that sees both the service and the viewer: ``web`` builds on ``app``, and ``app``
never imports ``web``.
"""

from app import __version__ as __version__
