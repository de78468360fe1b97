"""Per-epoch SPICE calls in one loop, without spiceypy's per-call wrapping.

spiceypy encodes the strings, allocates the output and checks SPICE's error state at
every call (about 20 us per call, more than ``pxform_c`` of a C-kernel frame itself); the
verified interpolation of frames and positions makes a few thousand such calls per day.
These loops call the same CSPICE routines (``pxform_c``, ``spkezr_c``) through
spiceypy's own ctypes binding, with the strings encoded once and the results written in
place, and check the error state once at the end: the values are those of
``spiceypy.pxform``/``spiceypy.spkezr``, bit for bit.

spiceypy sets SPICE's error action to RETURN when imported: after an error, the
remaining calls return at once.  On an error these loops reset the error state and
return False; callers then repeat the calls through spiceypy, which raises naming the
failing epoch (`fluxcal.geometry.frames.pxform_oracle`,
`fluxcal.geometry.positions.states_oracle`).

References
----------
.. [1] NAIF, CSPICE ``pxform_c``, ``spkezr_c``, ``failed_c``, ``reset_c``.
"""

from __future__ import annotations

import ctypes

import numpy as np
from spiceypy.utils.libspicehelper import libspice


def _succeeded() -> bool:
    """Return False (after resetting SPICE's error state) when a call signalled an error."""
    if libspice.failed_c():
        libspice.reset_c()
        return False
    return True


def pxform_into(from_frame: str, to_frame: str, et: np.ndarray, out: np.ndarray) -> bool:
    """``out[i] = pxform(from_frame, to_frame, et[i])``; False when SPICE signalled an error.

    Parameters
    ----------
    from_frame, to_frame : str
        SPICE frame names.
    et : ndarray, shape (n,)
        Epochs.
    out : ndarray, shape (n, 3, 3)
        C-contiguous float64, written in place (undefined after an error).
    """
    if out.shape != (et.size, 3, 3) or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ValueError("out must be a C-contiguous float64 array of shape (n, 3, 3)")
    if et.size == 0:
        return True
    view = (ctypes.c_double * 3 * 3 * et.size).from_address(out.ctypes.data)
    call = libspice.pxform_c
    source, target = from_frame.encode(), to_frame.encode()
    for i, t in enumerate(np.asarray(et, dtype=float).tolist()):
        call(source, target, t, view[i])
    return _succeeded()


def spkezr_into(
    target: str, observer: str, frame: str, et: np.ndarray, out: np.ndarray
) -> bool:
    """``out[i] = spkezr(target, et[i], frame, "NONE", observer)[0]``; False on an error.

    Parameters
    ----------
    target, observer : str
        SPICE body names or ids.
    frame : str
        Frame of the states.
    et : ndarray, shape (n,)
        Epochs.
    out : ndarray, shape (n, 6)
        C-contiguous float64 states (km, km/s), written in place (undefined after an error).
    """
    if out.shape != (et.size, 6) or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ValueError("out must be a C-contiguous float64 array of shape (n, 6)")
    if et.size == 0:
        return True
    view = (ctypes.c_double * 6 * et.size).from_address(out.ctypes.data)
    light_time = ctypes.c_double()
    call = libspice.spkezr_c
    targ, obs, ref = target.encode(), observer.encode(), frame.encode()
    for i, t in enumerate(np.asarray(et, dtype=float).tolist()):
        call(targ, t, ref, b"NONE", obs, view[i], ctypes.byref(light_time))
    return _succeeded()
