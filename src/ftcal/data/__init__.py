"""From files to numbers: tables (CSV, Parquet; whole or in chunks), robot logs (YARP
``.mat``, CSV), ROS 1/2 bags and tf chains, stream alignment on one clock, signal checks,
static holds (``holds``: which samples were taken still), and the statistics of a fit streamed file by file (``streaming``).

Readers are found through one suffix → reader registry (``logs.READERS``). May import
:mod:`ftcal.core` and :mod:`ftcal.runtime`.
"""
