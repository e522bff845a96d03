"""The kinoplan service: REST API, job pool and settings. Start it with ``python -m app``."""

__version__ = "0.1.0"
