KPL/FK

fluxcal frames kernel: MESSENGER Radial-Tangential-Normal frame, MSGR_RTN
===========================================================================

   Source: MESSENGER MAG EDR-to-CDR Processing v2i, sec. 3.5 (seed 000).

   Origin: the spacecraft (MESSENGER, NAIF id -236).
   +R (X): from Sun centre to the spacecraft.
   +T (Y): Omega_sun x R, the cross product of the solar rotation axis and R (lies
           in the solar equatorial plane).
   +N (Z): R x T, the projection of the solar rotation axis on the plane of the sky.

   Implemented as a two-vector frame: primary +X along the Sun->spacecraft position,
   secondary +Z along the solar rotation axis (the +Z axis of IAU_SUN, a constant
   vector in IAU_SUN).  SPICE keeps the component of the secondary vector orthogonal
   to X, which is N; Y = Z x X = N x R = T.

\begindata

   FRAME_MSGR_RTN                 = 1499003
   FRAME_1499003_NAME             = 'MSGR_RTN'
   FRAME_1499003_CLASS            = 5
   FRAME_1499003_CLASS_ID         = 1499003
   FRAME_1499003_CENTER           = -236
   FRAME_1499003_RELATIVE         = 'J2000'
   FRAME_1499003_DEF_STYLE        = 'PARAMETERIZED'
   FRAME_1499003_FAMILY           = 'TWO-VECTOR'
   FRAME_1499003_PRI_AXIS         = 'X'
   FRAME_1499003_PRI_VECTOR_DEF   = 'OBSERVER_TARGET_POSITION'
   FRAME_1499003_PRI_OBSERVER     = 'SUN'
   FRAME_1499003_PRI_TARGET       = '-236'
   FRAME_1499003_PRI_ABCORR       = 'NONE'
   FRAME_1499003_SEC_AXIS         = 'Z'
   FRAME_1499003_SEC_VECTOR_DEF   = 'CONSTANT'
   FRAME_1499003_SEC_FRAME        = 'IAU_SUN'
   FRAME_1499003_SEC_SPEC         = 'RECTANGULAR'
   FRAME_1499003_SEC_VECTOR       = ( 0, 0, 1 )

\begintext
