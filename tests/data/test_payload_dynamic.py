"""Dynamic identification (10 inertial parameters + bias) on wrenches simulated by iDynTree, and compensation."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_payload_regressor import COM, IXX, IXY, IXZ, IYY, IYZ, IZZ, MASS, ONE_LINK_URDF, RPY, idyntree_measurements

from ftcal.payload.accumulate import payload_statistics
from ftcal.payload.compensate import contact_wrench, payload_wrench
from ftcal.payload.identify import identify_from_statistics
from ftcal.payload.kinematics import Kinematics
from ftcal.payload.parameters import PayloadParameters
from ftcal.payload.regressor import inertia_matrix
from ftcal.runtime.errors import UndeterminedWarning

BIAS = np.array([1.5, -0.7, 2.0, 0.05, 0.02, -0.03])
NOISE = np.array([0.05, 0.05, 0.05, 0.002, 0.002, 0.002])


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "one_link.urdf"
    path.write_text(ONE_LINK_URDF)
    rng = np.random.default_rng(21)
    n = 400
    gravity = Rotation.random(n, random_state=4).inv().apply([0.0, 0.0, -9.81])
    proper = -gravity + rng.normal(0.0, 3.0, (n, 3))
    omega = rng.normal(0.0, 2.0, (n, 3))
    alpha = rng.normal(0.0, 6.0, (n, 3))
    exact = idyntree_measurements(path, proper, omega, alpha)
    measured = exact + BIAS + rng.normal(size=exact.shape) * NOISE
    return Kinematics(gravity, omega, alpha, proper), exact, measured


def test_dynamic_fit_recovers_urdf_inertia(simulated):
    kinematics, _, measured = simulated
    # 20 contiguous blocks: held-out evidence for the weighting and cluster-robust standard errors.
    blocks = [payload_statistics(measured[i], kinematics.take(i), dynamic=True)
              for i in np.array_split(np.arange(len(measured)), 20)]
    fit = identify_from_statistics({"all": payload_statistics(measured, kinematics, dynamic=True)}, clusters=blocks)
    assert fit.weighting == "wls", fit.weighting_evidence  # torques are 25x less noisy than forces: weighting wins held out
    rot = Rotation.from_euler("xyz", RPY).as_matrix()
    inertia_com = rot @ inertia_matrix([IXX, IXY, IXZ, IYY, IYZ, IZZ]) @ rot.T
    assert abs(fit.mass - MASS) < 4 * fit.stderr["mass"]
    assert np.all(np.abs(fit.com - COM) < 4 * fit.stderr["com"])
    assert np.all(np.abs(fit.force_bias - BIAS[:3]) < 4 * fit.stderr["force_bias"])
    assert np.all(np.abs(fit.torque_bias - BIAS[3:]) < 4 * fit.stderr["torque_bias"])
    assert np.all(np.abs(fit.inertia - inertia_com) < 4 * fit.stderr["inertia"] + 1e-12)
    np.testing.assert_allclose(fit.residual_rms, NOISE, rtol=0.15)


def test_compensation_leaves_noise_only(simulated):
    kinematics, exact, measured = simulated
    rot = Rotation.from_euler("xyz", RPY).as_matrix()
    payload = PayloadParameters(MASS, COM, BIAS[:3], BIAS[3:], 9.81,
                                inertia=rot @ inertia_matrix([IXX, IXY, IXZ, IYY, IYZ, IZZ]) @ rot.T)
    np.testing.assert_allclose(payload_wrench(payload, kinematics), exact, atol=1e-9)
    contact = contact_wrench(measured, payload, kinematics)
    np.testing.assert_allclose(np.sqrt(np.mean(contact ** 2, axis=0)), NOISE, rtol=0.15)


def test_rotation_about_one_axis_leaves_inertia_undetermined():
    n = 200
    rng = np.random.default_rng(0)
    gravity = Rotation.random(n, random_state=1).inv().apply([0.0, 0.0, -9.81])
    omega = np.zeros((n, 3))
    alpha = np.zeros((n, 3))
    omega[:, 2] = rng.normal(0.0, 2.0, n)  # spinning about the sensor's z axis only
    alpha[:, 2] = rng.normal(0.0, 5.0, n)
    kinematics = Kinematics(gravity, omega, alpha)
    wrench = rng.normal(size=(n, 6))
    with pytest.warns(UndeterminedWarning, match=r"Ixx is not determined: .*about the sensor's x axis.*"
                                                  r"Not determined: Ixx, Ixy, Iyy"):
        result = identify_from_statistics({"a": payload_statistics(wrench, kinematics, dynamic=True)})
    assert np.all(np.isnan(result.stderr["inertia"]))


def test_cli_dynamic_identification_and_compensation(simulated, tmp_path, capsys):
    import json

    import pandas as pd

    from ftcal.cli import main

    kinematics, exact, measured = simulated
    columns = {"gx": kinematics.gravity, "wx": kinematics.angular_velocity, "alx": kinematics.angular_acceleration,
               "ax": kinematics.proper_acceleration, "u1": measured}
    names = {"gx": ["gx", "gy", "gz"], "wx": ["wx", "wy", "wz"], "alx": ["alx", "aly", "alz"],
             "ax": ["ax", "ay", "az"], "u1": ["u1", "u2", "u3", "u4", "u5", "u6"]}
    frame = pd.concat([pd.DataFrame(v, columns=names[k]) for k, v in columns.items()], axis=1)
    data = tmp_path / "motion.parquet"
    frame.to_parquet(data)
    options = ["--gravity-columns", "gx,gy,gz", "--dynamic", "--angular-acceleration", "alx,aly,alz"]
    assert main(["payload", str(data), *options, "-o", str(tmp_path / "p.json")]) == 0
    out = capsys.readouterr().out
    assert "dynamic (inertia included)" in out and "Ixx (com)" in out
    doc = json.loads((tmp_path / "p.json").read_text())
    rot = Rotation.from_euler("xyz", RPY).as_matrix()
    inertia_com = rot @ inertia_matrix([IXX, IXY, IXZ, IYY, IYZ, IZZ]) @ rot.T
    assert np.all(np.abs(np.array(doc["inertia"]) - inertia_com) < 4 * np.array(doc["stderr"]["inertia"]) + 1e-12)
    assert main(["compensate", str(tmp_path / "p.json"), str(data), *options, "-o", str(tmp_path / "c.csv")]) == 0
    contact = pd.read_csv(tmp_path / "c.csv")[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    np.testing.assert_allclose(np.sqrt(np.mean(contact ** 2, axis=0)), NOISE, rtol=0.2)
