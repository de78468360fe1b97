"""IMAP MAG: CCSDS packets (XTCE) -> L1A counts with SCLK times -> L1B nT (issue 24).

Pure functions for the mission contract: `packets.read_packets`, `l1a.from_packets`,
`l1a.read_l1a_csv`, `l1b.calibrate`, `calibration.load_calibration`,
`chain.process` / `products.products`; the command is `cli.app`.  ``__all__``
lists the public modules (the command line and the demo are internal).
"""

__all__ = [
    "api",
    "cadence",
    "calibration",
    "chain",
    "l1a",
    "l1b",
    "l1c",
    "l2",
    "mission",
    "options",
    "packets",
    "products",
    "sources",
    "team_layout",
    "vectors",
]
