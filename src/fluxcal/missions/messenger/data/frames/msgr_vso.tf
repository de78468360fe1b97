KPL/FK

fluxcal frames kernel: Venus Solar Orbital (VSO) frame, MSGR_VSO
=====================================================================

   Source: MESSENGER MAG EDR-to-CDR Processing v2i, sec. 3.3 (seed 000): "The Venus-centered Venus solar orbital (VSO) coordinate system is similarly defined."

   Origin: Venus centre.
   +X    : from Venus centre toward the Sun (position of the Sun as seen from
           Venus, no aberration correction).
   -Y    : the projection of Venus's velocity relative to the Sun onto the plane
           normal to X (Y is nominally opposite Venus's orbital velocity).
   +Z    : X cross Y, northward, normal to Venus's orbit plane.

   Two-vector dynamic frame relative to J2000.  fluxcal loads this file only when the
   loaded kernels do not already define MSGR_VSO (e.g. the mission's msgr_dyn kernel).
   The frame ID is in the range NAIF leaves for user-defined frames (1400000-2000000).

\begindata

   FRAME_MSGR_VSO                 = 1499002
   FRAME_1499002_NAME             = 'MSGR_VSO'
   FRAME_1499002_CLASS            = 5
   FRAME_1499002_CLASS_ID         = 1499002
   FRAME_1499002_CENTER           = 299
   FRAME_1499002_RELATIVE         = 'J2000'
   FRAME_1499002_DEF_STYLE        = 'PARAMETERIZED'
   FRAME_1499002_FAMILY           = 'TWO-VECTOR'
   FRAME_1499002_PRI_AXIS         = 'X'
   FRAME_1499002_PRI_VECTOR_DEF   = 'OBSERVER_TARGET_POSITION'
   FRAME_1499002_PRI_OBSERVER     = 'VENUS'
   FRAME_1499002_PRI_TARGET       = 'SUN'
   FRAME_1499002_PRI_ABCORR       = 'NONE'
   FRAME_1499002_SEC_AXIS         = '-Y'
   FRAME_1499002_SEC_VECTOR_DEF   = 'OBSERVER_TARGET_VELOCITY'
   FRAME_1499002_SEC_OBSERVER     = 'SUN'
   FRAME_1499002_SEC_TARGET       = 'VENUS'
   FRAME_1499002_SEC_ABCORR       = 'NONE'
   FRAME_1499002_SEC_FRAME        = 'J2000'

\begintext
