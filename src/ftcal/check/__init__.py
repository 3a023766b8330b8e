"""``ftcal check``: is the sensor signed, mounted and zeroed the way the user thinks, and does
the installation pass?

* :mod:`.conventions` reads the static holds of a recording (:mod:`ftcal.data.holds`, from the
  gravity direction) and infers sign, handedness, axis permutation, frame rotation, a wrench
  already tared / gravity-compensated / in the base frame, and torques about another point,
  each with a confidence, the fix and the residual before and after it;
* :mod:`.accept` tests a calibration (and payload) against thresholds on a test recording;
* :mod:`.history` keeps the per-sensor SQLite history of calibrations and acceptance results;
* :mod:`.page` writes the HTML page with the report machinery.

May import :mod:`ftcal.insitu`, :mod:`ftcal.report`, :mod:`ftcal.files`, :mod:`ftcal.robot`,
:mod:`ftcal.payload`, :mod:`ftcal.data`, :mod:`ftcal.core` and :mod:`ftcal.runtime`; only
:mod:`ftcal.sim` and :mod:`ftcal.cli` import it.
"""
