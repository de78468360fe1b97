"""The installed fluxcal version, read once from the package metadata.

A module of its own so that the writers, provenance and the batch runner can name the
version without importing the ``fluxcal`` package namespace (and the API it exposes).
"""

from functools import cache
from importlib.metadata import PackageNotFoundError, version


@cache
def software_version() -> str:
    """Return the installed distribution's version (``importlib.metadata``, read once)."""
    try:
        return version("fluxcal")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0.0.0+unknown"
