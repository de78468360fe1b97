KPL/FK

fluxcal frames kernel: comet-centred solar equatorial frame, 67P/C-G_CSEQ
===========================================================================

   Source: Rosetta RPC-MAG calibration, sec. 4.4 (seed 003), and the definition used
   by the Rosetta frames kernel (ROS_V38.TF, 67P/C-G_CSEQ).

   Origin: comet 67P/Churyumov-Gerasimenko (NAIF id 1000012).
   +X    : from the comet centre toward the Sun.
   +Z    : the component of the Sun's rotation axis (+Z of IAU_SUN) orthogonal to X.
   +Y    : completes the right-handed system.

   Needs an SPK for the comet (user supplied).  Loaded only when the user's kernels do
   not define 67P/C-G_CSEQ already (the mission frames kernel does).

\begindata

   FRAME_67P/C-G_CSEQ             = 1499010
   FRAME_1499010_NAME             = '67P/C-G_CSEQ'
   FRAME_1499010_CLASS            = 5
   FRAME_1499010_CLASS_ID         = 1499010
   FRAME_1499010_CENTER           = 1000012
   FRAME_1499010_RELATIVE         = 'J2000'
   FRAME_1499010_DEF_STYLE        = 'PARAMETERIZED'
   FRAME_1499010_FAMILY           = 'TWO-VECTOR'
   FRAME_1499010_PRI_AXIS         = 'X'
   FRAME_1499010_PRI_VECTOR_DEF   = 'OBSERVER_TARGET_POSITION'
   FRAME_1499010_PRI_OBSERVER     = '1000012'
   FRAME_1499010_PRI_TARGET       = 'SUN'
   FRAME_1499010_PRI_ABCORR       = 'NONE'
   FRAME_1499010_SEC_AXIS         = 'Z'
   FRAME_1499010_SEC_VECTOR_DEF   = 'CONSTANT'
   FRAME_1499010_SEC_FRAME        = 'IAU_SUN'
   FRAME_1499010_SEC_SPEC         = 'RECTANGULAR'
   FRAME_1499010_SEC_VECTOR       = ( 0, 0, 1 )

\begintext
