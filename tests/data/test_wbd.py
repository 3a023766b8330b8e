"""wholeBodyDynamics groups: values by hand and the device's own correction formula."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ftcal.core.conversion import from_raw
from ftcal.files.model_files import save_model
from ftcal.files.wbd import format_wbd
from ftcal.runtime.errors import FtcalError

CHANNELS = ["Fx_in", "Fy_in", "Fz_in", "Tx_in", "Ty_in", "Tz_in"]
OUTPUTS = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
C = np.eye(6) + 0.01 * np.arange(36).reshape(6, 6)
K = np.array([0.5, -0.2, 1.0, 0.0, 0.01, -0.03])
O = np.array([1.0, 2.0, -3.0, 0.1, 0.2, 0.3])


def groups(text):
    """{group: values} parsed from the XML text."""
    found = re.findall(r'<group name="(\w+)">\s*<param name="r_arm_ft_sensor">\(([^)]*)\)</param>', text)
    return {name: np.array([float(v) for v in values.split(",")]) for name, values in found}


def temperature_model():
    raw = np.vstack([C.T, K, O])  # y = C u + K T + O
    return from_raw(raw, degree=1, input_names=CHANNELS + ["T"], output_names=OUTPUTS,
                    input_range=np.r_[np.tile([-100.0, 100.0], (6, 1)), [[20.0, 40.0]]])


def test_groups_by_hand():
    g = groups(format_wbd(temperature_model(), "r_arm_ft_sensor"))
    np.testing.assert_allclose(g["FT_SECONDARY_CALIBRATION"], C.ravel(), rtol=1e-14)
    # T_ref = middle of the training range [20, 40] = 30; offset = −(O + 30 K).
    np.testing.assert_allclose(g["FT_TEMPERATURE_COEFFICIENTS"], np.r_[K, 30.0], rtol=1e-14)
    np.testing.assert_allclose(g["FT_OFFSET"], -(O + 30 * K), rtol=1e-14)


def test_device_formula_reproduces_the_model():
    model = temperature_model()
    g = groups(format_wbd(model, "r_arm_ft_sensor", reference_temperature=25.0))
    secondary = g["FT_SECONDARY_CALIBRATION"].reshape(6, 6)
    k, t_ref = g["FT_TEMPERATURE_COEFFICIENTS"][:6], g["FT_TEMPERATURE_COEFFICIENTS"][6]
    rng = np.random.default_rng(0)
    w, t = rng.uniform(-50, 50, 6), 33.0
    # wholeBodyDynamics: C · w − offset + k · (T − T_ref).
    device = secondary @ w - g["FT_OFFSET"] + k * (t - t_ref)
    np.testing.assert_allclose(device, model.predict(np.r_[w, t][None])[0], rtol=1e-12)


def test_no_temperature_group_without_a_temperature_input(tmp_path):
    model = from_raw(np.vstack([C.T, O]), degree=1, input_names=CHANNELS, output_names=OUTPUTS)
    path = save_model(model, tmp_path / "wbd.xml", "wbd", sensor="r_arm_ft_sensor")
    g = groups(path.read_text())
    assert set(g) == {"FT_SECONDARY_CALIBRATION", "FT_OFFSET"}
    np.testing.assert_allclose(g["FT_OFFSET"], -O)


def test_refusals():
    quadratic = from_raw(np.vstack([C.T, np.zeros((21, 6)), O]), degree=2, input_names=CHANNELS,
                         output_names=OUTPUTS)
    quadratic.coef_[6, 0] = 1e-6  # Fx_in²
    with pytest.raises(FtcalError, match=r"wholeBodyDynamics .* term 'Fx_in\^2'"):
        format_wbd(quadratic, "r_arm_ft_sensor")
    eight = from_raw(np.zeros((9, 6)), degree=1, input_names=CHANNELS + ["T", "V"], output_names=OUTPUTS)
    with pytest.raises(FtcalError, match="this model has 8 inputs and 6 outputs"):
        format_wbd(eight, "r_arm_ft_sensor")
    with pytest.raises(FtcalError, match="not a valid wholeBodyDynamics parameter name"):
        format_wbd(temperature_model(), "r arm")
    with pytest.raises(FtcalError, match="needs the sensor name"):
        save_model(temperature_model(), "unused.xml", "wbd")


def test_convert_writes_the_temperature_group(tmp_path, capsys):
    from ftcal.cli import main
    from ftcal.files.model_files import save_model

    path = tmp_path / "affine-t.json"
    save_model(temperature_model(), path)
    out = tmp_path / "wbd.xml"
    assert main(["convert", str(path), "--to", "wbd", "--sensor", "r_arm_ft_sensor", "-o", str(out)]) == 0
    g = groups(out.read_text())
    # By hand: k = K, T_ref = (20 + 40) / 2 = 30, FT_OFFSET = −(O + 30 K); e.g. Fx: −(1 + 15) = −16.
    np.testing.assert_allclose(g["FT_TEMPERATURE_COEFFICIENTS"], [0.5, -0.2, 1.0, 0.0, 0.01, -0.03, 30.0],
                               rtol=1e-14)
    np.testing.assert_allclose(g["FT_OFFSET"], [-16.0, 4.0, -27.0, -0.1, -0.5, 0.6], rtol=1e-13)
