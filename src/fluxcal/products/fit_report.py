"""Write the pictures of a fit (`fluxcal.products.fit_pictures`) and its ``index.html``.

`write_fit_report` draws them (matplotlib, the ``plot`` extra: `fluxcal.products.fit_plots`)
into the fit's output folder and writes that folder's ``index.html`` with the run-report
machinery of the calibration runs (`fluxcal.products.html_report.write_run_report`):
pictures with a caption saying what each shows, the text reports, every file of the
folder linked relatively (those already in place and those the run still stages).
Without matplotlib the index is written without pictures and the returned note says,
in one line, that they need ``fluxcal[plot]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from fluxcal.extras import available
from fluxcal.products.atomic import ungrouped
from fluxcal.products.fit_pictures import Picture
from fluxcal.products.html_report import run_products, write_run_report

#: The one line a fit prints when matplotlib is missing.
NO_PLOT_NOTE = "fit pictures need matplotlib: install fluxcal[plot] (the index lists the tables)"


def write_fit_report(out: Path, pictures: Sequence[Picture], title: str
                     ) -> tuple[list[Path], str]:
    """Draw ``pictures`` into ``out`` (PNG) and write ``out/index.html``.

    Parameters
    ----------
    out : Path
        The fit's output folder (its tables already written).
    pictures : sequence of Panel, Pulls, Rejections
        What to draw, in page order.
    title : str
        Page title.

    Returns
    -------
    list of Path
        The pictures and the index written.
    str
        `NO_PLOT_NOTE` when matplotlib is missing (no picture drawn), else ``""``.
    """
    out = Path(out)
    written: list[Path] = []
    note = ""
    if available("plot"):
        from fluxcal.products.fit_plots import draw_picture  # the plot extra

        written = [draw_picture(p, out / f"{p.name}.png") for p in pictures]
    else:
        note = NO_PLOT_NOTE
    captions = {f"{p.name}.png": p.caption for p in pictures}
    with ungrouped():  # what is in the folder already (tables some fits rename at once)
        files = {f.rel: f for f in run_products(out)}
    files.update({f.rel: f for f in run_products(out)})  # and what the run stages
    index = write_run_report(out, title, [files[k] for k in sorted(files)],
                             captions=captions, no_figures=note or "This fit drew no picture.")
    return written + ([index] if index is not None else []), note
