"""Readers of archived (PDS3) products: the label-driven table reader and product readers.

* `fluxcal.archive.pds3`: `read_label`, `read_table`, `read_table_columns` -- any PDS3
  ``TABLE`` (ASCII or binary) described by a detached or attached label, into an
  xarray Dataset with units and descriptions from the label.
* `fluxcal.archive.products`: `read_archive_product` -- archived calibrated products in the
  Dataset shape of fluxcal's own products, through the readers each mission ships
  (each mission package's ``archive_products``, handed down by the registry).

See ``docs/formats/archive.md``.
"""

from fluxcal.archive.pds3 import read_label, read_table, read_table_columns

#: The public names: the table reader and the public modules (the API reference's pages).
__all__ = ["pds3", "products", "read_label", "read_table", "read_table_columns"]
