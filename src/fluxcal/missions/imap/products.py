"""The products of an IMAP MAG run: one per (mode, sensor) and UTC day.

`products` declares them (`fluxcal.products.declared`) named
``imap_mag_<level>_<mode>-<sensor>_<yyyymmdd>_v<nnn>`` from the ISTP logical source
(`logical_source`), in fluxcal's or the team's CDF layout; the runner writes them
(`fluxcal.runs.driver.write`).  The datasets come from `fluxcal.missions.imap.chain`.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import xarray as xr

from fluxcal.missions.imap import team_layout
from fluxcal.missions.imap.packets import data_file
from fluxcal.products.declared import Declared, Product, Quicklook

DATA_VERSION = "001"


def logical_source(level: str, mode: str, sensor: str) -> str:
    """IMAP logical source, e.g. ``imap_mag_l1b_norm-mago``."""
    return f"imap_mag_{level}_{mode}-{sensor}"


def products(datasets: dict[tuple[str, str], xr.Dataset], formats: Sequence[str] = ("cdf",),
             *, quicklook: bool = False, layout: str = "fluxcal",
             version: str = DATA_VERSION) -> Iterator[Declared]:
    """Declare one product per (mode, sensor) and UTC day (`fluxcal.products.declared`).

    Named ``imap_mag_<level>_<mode>-<sensor>_<yyyymmdd>_v<nnn>`` as the team's files;
    the runner splits each dataset by UTC day, adds the provenance and writes.  With
    ``layout="team"`` the products hold the team's CDF variables
    (`fluxcal.missions.imap.team_layout.team_product`); with ``quicklook`` an L1B
    dataset also gets ``imap_mag_ql_<mode>-<sensor>_<yyyymmdd>.png``.
    """
    for (mode, sensor), ds in datasets.items():
        level = ds.attrs["level"]
        source = logical_source(level, mode, sensor)
        if layout == "team":
            yield team_layout.team_product(ds, source, f"v{version}")
            continue
        yield Product(f"{source}_{{day:%Y%m%d}}_v{version}", ds, formats=tuple(formats),
                      attrs={"Logical_source": source, "Data_version": version,
                             "Data_type": f"{level.upper()}>{level.upper()} {mode}"},
                      global_yaml=data_file("istp_global.yaml"))
        if quicklook and level == "l1b":
            yield Quicklook(f"imap_mag_ql_{mode}-{sensor}", ds, field="b",
                            frame="sensor unit frame")
