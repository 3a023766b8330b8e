"""The one-line text of training metrics, without numpy (``ftcal info`` prints it; numpy stays unloaded)."""

from __future__ import annotations


def norm_rmse_text(metrics: dict, spec: str = ".4f", units: bool = True) -> str:
    """``force-norm RMSE … N, torque-norm RMSE … N·m`` from training metrics; either may be absent
    (force-only or torque-only outputs); '' when both are.

    Examples
    --------
    >>> norm_rmse_text({"force_norm_rmse": 1.5, "torque_norm_rmse": None})
    'force-norm RMSE 1.5000 N'
    """
    parts = [f"{what}-norm RMSE {metrics[key]:{spec}}" + (f" {unit}" if units else "")
             for what, key, unit in (("force", "force_norm_rmse", "N"), ("torque", "torque_norm_rmse", "N·m"))
             if metrics.get(key) is not None]
    return ", ".join(parts)
