"""The names of the product formats (no imports: the command line reads them at start-up).

``tab`` (fixed-width ``.TAB`` + PDS3 ``.LBL``), ``cdf`` (ISTP), ``nc`` (netCDF),
``zarr``; `fluxcal.products.writer.write_product` writes each.
"""

FORMATS = ("tab", "cdf", "nc", "zarr")
