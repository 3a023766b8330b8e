"""Small synthetic tables for the CLI tests, and references computed without ftcal.

The truth is a known polynomial of the raw inputs (an affine map plus a few
quadratic and cubic terms) with a little Gaussian noise, so a degree-3 fit is
right, a degree-1 fit is not, and every reference number below comes from plain
numpy on the same arrays the tests write to disk.
"""

from __future__ import annotations

from itertools import combinations_with_replacement
from math import comb

import numpy as np
import pandas as pd

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
U_SPAN = 2.0  # raw channels in [-2, 2] (volts, say)
T_RANGE = (25.0, 40.0)  # temperature, °C
NOISE = 0.01

# Affine part: outputs × (u1..u6, T), then offsets. Fixed numbers, no ftcal involved.
GAIN = np.random.default_rng(7).uniform(-20.0, 20.0, size=(6, 7))
GAIN[:, 6] *= 0.01  # a mild temperature drift
OFFSET = np.array([3.0, -2.0, 40.0, 0.5, -0.25, 0.1])


def truth(u: np.ndarray) -> np.ndarray:
    """The true outputs of raw inputs ``u`` (n, 7): affine plus quadratic and cubic terms."""
    y = u @ GAIN.T + OFFSET
    y[:, 0] += 1.5 * u[:, 0] * u[:, 1]
    y[:, 2] += 0.8 * u[:, 2] ** 3
    y[:, 4] -= 0.3 * u[:, 3] ** 2 * u[:, 4]
    y[:, 5] += 0.02 * (u[:, 6] - 30.0) ** 2
    return y


def random_inputs(rng: np.random.Generator, n: int, shrink: float = 1.0) -> np.ndarray:
    """Inputs (n, 7) uniform in the training box, optionally shrunk towards its centre."""
    u = rng.uniform(-U_SPAN * shrink, U_SPAN * shrink, size=(n, 6))
    mid, half = np.mean(T_RANGE), np.ptp(T_RANGE) / 2 * shrink
    return np.c_[u, rng.uniform(mid - half, mid + half, size=n)]


def frame(u: np.ndarray, y: np.ndarray | None, **extra) -> pd.DataFrame:
    """A table with the default column names (and any extra columns)."""
    columns = {name: u[:, j] for j, name in enumerate(INPUTS[:u.shape[1]])}
    if y is not None:
        columns.update({name: y[:, j] for j, name in enumerate(OUTPUTS)})
    columns.update(extra)
    return pd.DataFrame(columns)


def training_frame(rng: np.random.Generator, n: int = 600, n_groups: int = 4) -> pd.DataFrame:
    """``n`` noisy samples in ``n_groups`` contiguous groups (column ``load``), also segments (``rec``)."""
    u = random_inputs(rng, n)
    y = truth(u) + NOISE * rng.standard_normal((n, 6))
    label = np.repeat(np.arange(n_groups), -(-n // n_groups))[:n]
    return frame(u, y, load=[f"l{k}kg" for k in label], rec=label)


def validation_frame(rng: np.random.Generator, n: int = 200, n_outside: int = 3) -> pd.DataFrame:
    """Samples strictly inside the training box, then ``n_outside`` with u1 far beyond it."""
    u = random_inputs(rng, n, shrink=0.9)
    u[n - n_outside:, 0] = 3.0 * U_SPAN
    y = truth(u) + NOISE * rng.standard_normal((n, 6))
    return frame(u, y)


# ------------------------------------------------------------ independent references
def monomials(u: np.ndarray, degree: int) -> np.ndarray:
    """The paper's columns: degree-1..degree monomials (lexicographic, with replacement), offset last."""
    cols = [np.prod(u[:, list(c)], axis=1)
            for p in range(1, degree + 1) for c in combinations_with_replacement(range(u.shape[1]), p)]
    return np.column_stack(cols + [np.ones(len(u))])


def n_coefficients(n_inputs: int, degree: int, n_outputs: int, na: int = 0, nb: int = 0) -> int:
    """ny · (ny·na + 1 + Σ_p (nb+1)·C(nu+p−1, p)), the paper's count."""
    return n_outputs * (n_outputs * na + 1
                        + sum((nb + 1) * comb(n_inputs + p - 1, p) for p in range(1, degree + 1)))


def lstsq_predict(u_train: np.ndarray, y_train: np.ndarray, u: np.ndarray, degree: int) -> np.ndarray:
    """Least-squares polynomial fit with numpy on monomials of centred, scaled inputs."""
    centre = (u_train.max(axis=0) + u_train.min(axis=0)) / 2
    half = (u_train.max(axis=0) - u_train.min(axis=0)) / 2
    coef, *_ = np.linalg.lstsq(monomials((u_train - centre) / half, degree), y_train, rcond=None)
    return monomials((u - centre) / half, degree) @ coef


def metrics(y: np.ndarray, pred: np.ndarray) -> dict:
    """The paper's metrics by their definitions (RMSE, BestFit, max error, norm RMSEs)."""
    err = y - pred
    mse = np.mean(err ** 2, axis=0)
    norm = np.linalg.norm
    return {
        "rmse": np.sqrt(mse),
        "best_fit": 1.0 - np.sqrt(mse / np.mean((y - y.mean(axis=0)) ** 2, axis=0)),
        "max_abs_error": np.abs(err).max(axis=0),
        "force_norm_rmse": np.sqrt(np.mean((norm(y[:, :3], axis=1) - norm(pred[:, :3], axis=1)) ** 2)),
        "torque_norm_rmse": np.sqrt(np.mean((norm(y[:, 3:], axis=1) - norm(pred[:, 3:], axis=1)) ** 2)),
    }


def parse_paper_xml(path) -> tuple[dict[str, int], np.ndarray]:
    """The integer params and the rowK table of a paper XML file, read with the standard library."""
    import xml.etree.ElementTree as ET

    params = {p.get("name"): (p.text or "").strip() for p in ET.parse(path).getroot().iter("param")}
    ints = {k: int(params[k]) for k in ("np", "ny", "nu", "na", "nb")}
    n_rows = sum(1 for k in params if k.startswith("row"))
    rows = [[float(v) for v in params[f"row{k}"].strip("()").split()] for k in range(1, n_rows + 1)]
    return ints, np.array(rows)
