"""The missions: each folder holds one instrument's readers, levels and products.

Until the mission registry (issue 20) lists them, two tables here hand the generic code
what the missions ship, by name (no generic module imports a mission):

* `FRAME_KERNELS`: frame name -> frames kernel of every mission, the default of
  `fluxcal.geometry.kernels.KernelPool` (`fluxcal.geometry.kernels.DEFAULT_FRAMES`);
* ``ARCHIVED_READERS``: name -> `fluxcal.archive.products.ArchivedReader`, the default of
  `fluxcal.archive.products.read_product` (imported on first use: the readers need
  xarray, which ``fluxcal --help`` does not load).
"""

from __future__ import annotations

from typing import Any

from fluxcal.missions.messenger import identity as _messenger
from fluxcal.missions.rosetta import identity as _rosetta

FRAME_KERNELS = {**_messenger.FRAME_KERNELS, **_rosetta.FRAME_KERNELS}


def __getattr__(name: str) -> Any:
    if name == "ARCHIVED_READERS":
        from fluxcal.missions.messenger.archive_products import READER as messenger_reader
        from fluxcal.missions.rosetta.archive_products import READER as rosetta_reader

        return {"messenger": messenger_reader, "rosetta": rosetta_reader}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
