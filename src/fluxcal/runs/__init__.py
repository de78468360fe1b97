"""Runs: the mission contract, the registry of missions and the drivers that use them.

A mission (``fluxcal.missions.<name>``, or a package of your own) declares what it hands
the runner in one `~fluxcal.runs.contract.Mission` object, registered under the
entry-point group ``fluxcal.missions`` (`fluxcal.runs.registry`).  Everything generic is
done here once, for every mission:

- `fluxcal.runs.options`: a mission's run options as one dataclass, turned into the
  command-line options of its single-run command and of ``fluxcal batch <mission>``;
- `fluxcal.runs.batch`: one task per day on Dask (manifests, resumption, locks, report);
- `fluxcal.runs.cli`: ``fluxcal batch <mission>`` built from the registry;
- `fluxcal.runs.demo`: ``fluxcal demo``, the demo parts every mission declares.

Nothing in this package names a mission.  ``__all__`` lists the public modules (what a
plugin author uses); the command line, the demos and the synthetic mission are internal.
"""

__all__ = [
    "batch",
    "contract",
    "driver",
    "options",
    "registry",
]
