"""The kinoplan service: REST API, job pool and settings. ``python -m kinoplan`` starts it with
the 3D viewer, ``python -m app`` alone."""

__version__ = "0.1.0"
