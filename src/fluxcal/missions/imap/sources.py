"""Where IMAP MAG runs find the IMAP team's files, which fluxcal does not ship.

The SCLK kernel, the L1B calibration CDF and the XTCE packet definition come from the
IMAP MAG team (MIT License): a user names them (``--kernels``, ``--calib``,
``--xtce``), the packet definition is also taken from the team's package when installed
(`fluxcal.missions.imap.packets.xtce_path`).  The demo and the tests read the team's
published files from ``../shared/data/imap/`` beside the checkout when it is there
(`shared_folder`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from fluxcal.errors import InputFormatError

#: The team's files the demo uses, by role (names as published in imap_processing).
TEAM_FILES = {"sclk": "imap_sclk_0036.tsc",
              "calib": "imap_calibration_mag_20240229_v01.cdf",
              "xtce": "MAG_SCI_COMBINED.xml",
              "norm": "mag_l1_test_data.pkts",
              "burst": "mag_l0_test_data.pkts"}
#: Support files of a ``fluxcal batch imap`` input folder, by role: used when no option
#: names one (`fluxcal.missions.imap.routes.make_day_task`; the simulator's batch layout,
#: `fluxcal.missions.imap.simulate.simulate_days`, writes them).
BATCH_FILES = {"kernels": "kernels.tm", "calib": "calibration.cdf",
               "xtce": "packet_definition.xml"}
#: The folder of the team's files, relative to the folder that holds the checkout.
SHARED_IMAP = Path("shared") / "data" / "imap"


def shared_folder() -> Path | None:
    """``../shared/data/imap`` beside the checkout (or beside the working folder), if there.

    Looked for beside the source tree this module is in (a checkout) and beside the
    current working folder (``make demo`` runs in the checkout); None when neither
    holds every file of `TEAM_FILES`.
    """
    checkout = Path(__file__).resolve().parents[4]
    for root in (checkout.parent, Path.cwd().resolve().parent):
        folder = root / SHARED_IMAP
        if all((folder / name).is_file() for name in TEAM_FILES.values()):
            return folder
    return None


def missing_team_files() -> str:
    """One line saying what the IMAP demo needs and where it looks."""
    return (f"the IMAP MAG team's files ({', '.join(TEAM_FILES.values())}) were not found "
            f"in ../{SHARED_IMAP.as_posix()} beside the checkout; fluxcal does not ship "
            "them (they are the IMAP team's, from IMAP-Science-Operations-Center/"
            "imap_processing)")


def sclk_kernels(kernels: Path | str | Sequence[Path | str] | None) -> list[Path]:
    """Return the kernels the user named, as a list.

    Raises
    ------
    InputFormatError
        None named: IMAP times need the team's SCLK kernel (names ``--kernels``).
    """
    if kernels is None or (not isinstance(kernels, (str, Path)) and len(kernels) == 0):
        raise InputFormatError(
            "IMAP MAG times need the IMAP spacecraft clock kernel (NAIF -43, e.g. "
            f"../{SHARED_IMAP.as_posix()}/{TEAM_FILES['sclk']}): give --kernels PATH",
            field="--kernels")
    return [Path(kernels)] if isinstance(kernels, (str, Path)) else [Path(k) for k in kernels]
