"""The mission contract: what a mission hands the generic runner.

A mission is one `Mission` object.  Its pieces are named by reference
(``"package.module:attribute"``) and imported only when used, so building the command
line imports no mission's numerical code.

Example: a minimal mission with a batch day task (the template package
``templates/fluxcal-plugin-groundtest``, docs/guide/plugins.md)::

    MISSION = Mission(
        name="toy",
        title="Toy fluxgate",
        day_task="my_package.toy:make_day_task",
        options="my_package.toy:ToyOptions",
        simulate_days="my_package.toy:simulate_days",
        demo_days=(datetime.date(2024, 1, 1),),
    )

registered in the mission package's ``pyproject.toml``::

    [project.entry-points."fluxcal.missions"]
    toy = "my_package.toy:MISSION"
"""

from __future__ import annotations

import datetime as _dt
import importlib
from dataclasses import dataclass, field
from typing import Any

from fluxcal.errors import FluxcalError
from fluxcal.products.format_names import FORMATS


def load_reference(reference: str) -> Any:
    """Import ``"package.module:attribute"`` and return the attribute.

    Raises
    ------
    FluxcalError
        If the module or the attribute does not exist (the message names both).
    """
    module_name, _, attribute = reference.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        raise FluxcalError(f"{reference}: module {module_name} not found ({exc})") from exc
    try:
        value = module
        for part in attribute.split("."):
            value = getattr(value, part)
    except AttributeError as exc:
        raise FluxcalError(f"{reference}: {module_name} has no {attribute!r}") from exc
    return value


@dataclass(frozen=True)
class DemoPart:
    """One part of ``fluxcal demo``.

    Parameters
    ----------
    title : str
        Heading printed before the part runs.
    run : str
        Reference to ``run(out: Path) -> str`` (writes into ``out``, returns a summary).
    folder : str
        Sub-folder of the demo's ``--out`` for this part.
    order : int
        Position in the tour (parts of every mission sorted by it).
    quick : bool
        A part of the quick first run (``fluxcal demo``, ``make demo``: a calibrated
        product, a quicklook and the HTML report in seconds); the others make the full
        tour (``fluxcal demo --full``, ``make demo-full``).
    """

    title: str
    run: str
    folder: str
    order: int = 100
    quick: bool = False


@dataclass(frozen=True)
class Mission:
    """What a mission hands the runner; every piece but the name is optional.

    Parameters
    ----------
    name : str
        Command-line name (``fluxcal <name> ...``, ``fluxcal batch <name>``).
    title : str
        One line for help texts.
    spacecraft_id : int, optional
        NAIF id of the spacecraft (its SCLK kernel's id).
    commands : str, optional
        Reference to a callable returning the mission's `typer.Typer` app, or to the app
        itself (``fluxcal <name> ...``).
    simulate : str, optional
        Reference to the ``fluxcal simulate <name>`` command function.
    day_task : str, optional
        Reference to ``make_day_task(input_dir, out_dir, **options)`` returning a
        picklable ``task(day) -> fluxcal.runs.batch.DayResult`` (``fluxcal batch <name>``;
        `fluxcal.runs.driver.DayTask` is the ready-made task of a mission's
        `~fluxcal.runs.driver.Pipeline`).  ``options`` holds every field of the
        mission's ``options`` dataclass by its field name, with the values the command
        line or ``--config`` gave, checked and normalised (a tuple of formats, a `Path`:
        `fluxcal.runs.options.as_keywords`), and ``kernels`` (a `Path`) only when
        ``--kernels`` was given; nothing else: the batch's own options (``--start``,
        ``--scheduler``, ``--force`` ...) stay with the runner.  A mission without
        ``options`` gets ``kernels`` at most.
    options : str, optional
        Reference to the mission's run-options dataclass (`fluxcal.runs.options`): the
        options of ``fluxcal batch <name>`` beside the generic ones, the same dataclass
        its single-run command takes.
    formats : tuple of str, optional
        Formats its runs accept (default: the product writer's).
    simulate_days : str, optional
        Reference to ``simulate_days(input_dir, days)`` writing the day task's input
        layout (the batch demo, tests, benchmarks).
    demo_days : tuple of datetime.date
        Days the batch demo simulates and processes.
    demo_parts : tuple of DemoPart
        The mission's parts of ``fluxcal demo``.
    archived_products : str, optional
        Reference to the mission's `fluxcal.archive.products.ArchivedReader` (how its
        archived calibrated tables are recognised and read).
    frame_kernels : str, optional
        Reference to a mapping frame name -> frames kernel: the frames fluxcal defines for
        the mission, loaded by `fluxcal.geometry.kernels.KernelPool` for names the user's
        kernels do not define.
    before_batch : str, optional
        Reference to ``check(task) -> None`` called once before the days run (warnings
        about the calibration the task will use).
    calibrate : str, optional
        Reference to ``calibrate(inputs, **options) -> dict[str, xarray.Dataset]``, the
        mission's piece of `fluxcal.calibrate`: product kind (a frame, a level, ...) ->
        that full-resolution product's content in memory, with the variable and
        component names `fluxcal.read_product` reads back from the product (nothing
        written; docs/decisions/products.md, decision 72).
    """

    name: str
    title: str = ""
    spacecraft_id: int | None = None
    commands: str | None = None
    simulate: str | None = None
    day_task: str | None = None
    options: str | None = None
    formats: tuple[str, ...] | None = None
    simulate_days: str | None = None
    demo_days: tuple[_dt.date, ...] = ()
    demo_parts: tuple[DemoPart, ...] = field(default_factory=tuple)
    archived_products: str | None = None
    frame_kernels: str | None = None
    before_batch: str | None = None
    calibrate: str | None = None

    def load(self, piece: str) -> Any:
        """Return the object the reference ``piece`` (an attribute name) points to.

        Raises
        ------
        FluxcalError
            If the mission does not provide ``piece``.
        """
        reference = getattr(self, piece)
        if reference is None:
            raise FluxcalError(f"mission {self.name!r} provides no {piece.replace('_', ' ')}")
        return load_reference(reference)

    def accepted_formats(self) -> tuple[str, ...]:
        """Return the formats the mission's runs accept (its own, else the writer's)."""
        return tuple(self.formats if self.formats is not None else FORMATS)
