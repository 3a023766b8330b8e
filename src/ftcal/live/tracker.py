"""The recursive bias tracker's constants: a Kalman filter of the random-walk bias, gated by an innovation test.

Model, axis j (the random-walk model of :mod:`ftcal.payload.drift`, one sample at a time)::

    b_k = b_(k−1) + w_k,   w_k ~ N(0, q_j Δt_k)          (the sensor's bias walks)
    z_k = b_k + v_k,       v_k ~ N(0, r_j)                (z: calibrated wrench − tool's gravity wrench)

A wander (first-order Gauss-Markov, variance s², time constant τ) correlates ``v`` over τ; a filter whose time
constant is much longer than τ sees it as white noise of its low-frequency density ``D = 2 s² τ`` (N²·s). The
update then takes ``r_u = r + D / Δt`` per sample (the white noise whose density matches at the update rate),
the gate and the innovations keep ``S = P⁻ + r`` (what one sample shows): the bias is not pulled along by
the wander and a contact is still judged against one sample's spread. ``D = 0``: the plain filter.

A sample updates the filter only when it is *static* (the caller's motion test), its
innovation ``e = z − b_(k−1)`` passes the χ² test ``Σ_j e_j² / S_j < threshold`` with
``S = P⁻ + r`` (6 degrees of freedom), and it is not within :data:`HOLDOFF_S` s of the end of a run of
failed static samples lasting :data:`MIN_FAIL_S` or more (a contact's release edge stays out). A sample that fails
is a contact: it is reported and the bias is only predicted (``P`` grows by ``q Δt``), so a real contact is never
absorbed.

The filter itself is the C core's (``csrc/ftcal_live.h``, run by :class:`ftcal.live.LiveCalibrator` through the
extension :mod:`ftcal.live.core` and shipped by ``convert --to c-runtime``); this module holds the constants it is
configured with and the gate's threshold.
"""

from __future__ import annotations

# After a run of static samples that failed the gate for at least MIN_FAIL_S (a contact, not a chance failure), no
# sample updates the bias for HOLDOFF_S s: a contact released over tens of ms passes the gate part-way down its
# edge, and after a long contact the bias variance is large enough that one such sample would set the bias (gain
# near 1) to part of the contact. Chance failures (a bias a few σ off fails now and then) do not hold updates off.
HOLDOFF_S = 0.15
MIN_FAIL_S = 0.1


def gate_chi2(probability: float, dof: int = 6) -> float:
    """The innovation gate: the ``probability`` quantile of χ² with ``dof`` degrees of freedom.

    Parameters
    ----------
    probability : float
        Probability that a sample the model explains passes the gate (e.g. 0.999).
    dof : int, optional
        Degrees of freedom (6: the wrench's components).

    Returns
    -------
    float
        The threshold on the squared Mahalanobis norm of the innovation.
    """
    from scipy.special import chdtri  # what scipy.stats.chi2.ppf calls, without scipy.stats' 2 s of imports

    return float(chdtri(dof, 1.0 - probability))
