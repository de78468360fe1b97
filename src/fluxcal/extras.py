"""The optional parts of fluxcal (pip extras) and the one error when one is missing.

``pip install fluxcal`` (the core) reads every input, calibrates each mission and writes
every product format but Zarr; plots, Dask and Zarr are extras
(``pyproject.toml``, ``docs/decisions/packaging.md``):

========  ==============================  ============================================
extra     packages                        what needs it
========  ==============================  ============================================
plot      matplotlib                      ``--quicklook``, ``--formats png``, ``fluxcal
                                          plot``, ``fluxcal compare``, cleaning plots
batch     dask, distributed               ``fluxcal batch`` and ``messenger fit`` on a
                                          local cluster or ``--scheduler ADDRESS``
                                          (``--scheduler serial`` runs without it)
zarr      zarr                            ``--formats zarr``
========  ==============================  ============================================

The modules that use an extra import it at their top behind a guard that raises
`~fluxcal.errors.MissingExtraError` (`fluxcal.products.quicklook` for matplotlib,
`fluxcal.runs.cluster` for Dask); no core module imports them.  A command checks with
`require` before it reads any data, so a missing extra costs one line and exit code 2,
with nothing written.
"""

from __future__ import annotations

import importlib.util
from typing import Any

from fluxcal.errors import MissingExtraError

#: Extra -> the top-level modules it installs (``[project.optional-dependencies]``).
EXTRAS: dict[str, tuple[str, ...]] = {
    "plot": ("matplotlib",),
    "batch": ("dask", "distributed"),
    "zarr": ("zarr",),
}


def missing(extra: str) -> str | None:
    """Return the first module of ``extra`` that cannot be imported, or None.

    Examples
    --------
    >>> from fluxcal.extras import missing
    >>> missing("plot") in (None, "matplotlib")
    True
    """
    for module in EXTRAS[extra]:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):  # a broken or half-removed install
            found = False
        if not found:
            return module
    return None


def available(extra: str) -> bool:
    """Whether every package of ``extra`` is installed."""
    return missing(extra) is None


def require(extra: str, what: str) -> None:
    """Raise `~fluxcal.errors.MissingExtraError` unless ``extra`` is installed.

    Parameters
    ----------
    extra : str
        A key of `EXTRAS`.
    what : str
        What the user asked for, for the message (e.g. ``"--quicklook"``).

    Raises
    ------
    fluxcal.errors.MissingExtraError
        ``<what> needs <package>: install fluxcal[<extra>]``.
    """
    module = missing(extra)
    if module is not None:
        raise MissingExtraError(extra, what, module)


def guard(extra: str, what: str, exc: ImportError) -> MissingExtraError:
    """Return the error for a guarded top-of-module import of ``extra`` that failed.

    For ``except ImportError as exc: raise guard("plot", "quicklooks", exc) from exc``.
    """
    return MissingExtraError(extra, what, getattr(exc, "name", None) or EXTRAS[extra][0])


def require_for_options(options: Any) -> None:
    """Check the extras a mission's run options ask for, before any data is read.

    ``quicklook`` (true) and ``png`` in ``formats`` need ``plot``; ``zarr`` in
    ``formats`` needs ``zarr``.  Options without those fields need nothing.

    Raises
    ------
    fluxcal.errors.MissingExtraError
        Naming the option and the extra to install.
    """
    if getattr(options, "quicklook", False):
        require("plot", "--quicklook")
    formats = getattr(options, "formats", ()) or ()
    if isinstance(formats, str):
        formats = formats.split(",")
    if "png" in formats:
        require("plot", "--formats png")
    if "zarr" in formats:
        require("zarr", "--formats zarr")
