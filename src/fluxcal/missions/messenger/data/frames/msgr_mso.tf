KPL/FK

fluxcal frames kernel: Mercury Solar Orbital (MSO) frame, MSGR_MSO
=====================================================================

   Source: MESSENGER MAG EDR-to-CDR Processing v2i, sec. 3.3 (seed 000).

   Origin: Mercury centre.
   +X    : from Mercury centre toward the Sun (position of the Sun as seen from
           Mercury, no aberration correction).
   -Y    : the projection of Mercury's velocity relative to the Sun onto the plane
           normal to X (Y is nominally opposite Mercury's orbital velocity).
   +Z    : X cross Y, northward, normal to Mercury's orbit plane.

   Two-vector dynamic frame relative to J2000.  fluxcal loads this file only when the
   loaded kernels do not already define MSGR_MSO (e.g. the mission's msgr_dyn kernel).
   The frame ID is in the range NAIF leaves for user-defined frames (1400000-2000000).

\begindata

   FRAME_MSGR_MSO                 = 1499001
   FRAME_1499001_NAME             = 'MSGR_MSO'
   FRAME_1499001_CLASS            = 5
   FRAME_1499001_CLASS_ID         = 1499001
   FRAME_1499001_CENTER           = 199
   FRAME_1499001_RELATIVE         = 'J2000'
   FRAME_1499001_DEF_STYLE        = 'PARAMETERIZED'
   FRAME_1499001_FAMILY           = 'TWO-VECTOR'
   FRAME_1499001_PRI_AXIS         = 'X'
   FRAME_1499001_PRI_VECTOR_DEF   = 'OBSERVER_TARGET_POSITION'
   FRAME_1499001_PRI_OBSERVER     = 'MERCURY'
   FRAME_1499001_PRI_TARGET       = 'SUN'
   FRAME_1499001_PRI_ABCORR       = 'NONE'
   FRAME_1499001_SEC_AXIS         = '-Y'
   FRAME_1499001_SEC_VECTOR_DEF   = 'OBSERVER_TARGET_VELOCITY'
   FRAME_1499001_SEC_OBSERVER     = 'SUN'
   FRAME_1499001_SEC_TARGET       = 'MERCURY'
   FRAME_1499001_SEC_ABCORR       = 'NONE'
   FRAME_1499001_SEC_FRAME        = 'J2000'

\begintext
