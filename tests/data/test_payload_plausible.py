"""Payload files and loads with absurd values are refused; compensate uses the file's gravity (issue 28).

Truth from hand statics: a tool of mass m at rest under gravity g (sensor frame) adds m·g to the force.
"""

import json

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main
from ftcal.files.model_json import digest
from ftcal.files.payload_json import save_payload
from ftcal.payload.parameters import PayloadParameters
from ftcal.robot import parse_payload_spec
from ftcal.runtime.errors import FtcalError

AXES = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]


def payload_file(tmp_path, gravity=9.81, mass=1.5, columns=("u1", "u2", "u3", "u4", "u5", "u6")):
    stderr = {"mass": 0.01, "com": np.full(3, 0.001), "force_bias": np.full(3, 0.01), "torque_bias": np.full(3, 0.001)}
    fit = {"n_samples": 100, "residual_rms": np.full(6, 0.01), "condition_number": 3.0, "wrench_columns": list(columns)}
    payload = PayloadParameters(mass, np.array([0.0, 0.01, 0.05]), np.array([1.0, -2.0, 0.5]),
                                np.array([0.1, 0.0, -0.1]), gravity, stderr=stderr, fit=fit)
    path = tmp_path / "p.json"
    save_payload(payload, path)
    return path


def reseal(path, **changes):
    doc = json.loads(path.read_text())
    for key, value in changes.items():
        if key == "wrench_columns":
            doc["fit"][key] = value
        else:
            doc[key] = value
    doc["sha256"] = digest(doc)
    path.write_text(json.dumps(doc))
    return path


def poses(tmp_path, gravity, mass=1.5):
    rot = Rotation.random(20, random_state=3)
    g = rot.inv().apply([0.0, 0.0, -gravity])
    com, bias = np.array([0.0, 0.01, 0.05]), np.array([1.0, -2.0, 0.5, 0.1, 0.0, -0.1])
    wrench = np.c_[mass * g, np.cross(com, mass * g)] + bias
    frame = pd.DataFrame(np.c_[wrench, rot.as_quat()], columns=["u1", "u2", "u3", "u4", "u5", "u6",
                                                                "qx", "qy", "qz", "qw"])
    path = tmp_path / "poses.csv"
    frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("change, word", [({"mass": 1e308}, "mass"), ({"mass": 5e3}, "mass"),
                                          ({"gravity": 1e308}, "gravity"), ({"gravity": 1e-6}, "gravity"),
                                          ({"com": [1e300, 0, 0]}, "centre of mass"),
                                          ({"force_bias": [1e300, 0, 0]}, "force_bias"),
                                          ({"wrench_columns": ["u1"] * 6}, "repeats")])
def test_absurd_payload_files_are_refused_in_one_line(tmp_path, capsys, change, word):
    path = reseal(payload_file(tmp_path), **change)
    data = poses(tmp_path, 9.81)
    code = main(["compensate", str(path), str(data), "--orientation", "qx,qy,qz,qw", "-o", str(tmp_path / "c.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and word in err[0], err
    assert not (tmp_path / "c.csv").exists()


def test_compensate_uses_the_payload_files_gravity(tmp_path, capsys):
    """A tool identified on Mars (g = 3.71): compensating with Earth's 9.81 would leave 1.5·6.1 N behind."""
    path = payload_file(tmp_path, gravity=3.71)
    data = poses(tmp_path, 3.71)
    assert main(["compensate", str(path), str(data), "--orientation", "qx,qy,qz,qw", "-o", str(tmp_path / "c.csv")]) == 0
    contact = pd.read_csv(tmp_path / "c.csv")[AXES].to_numpy()
    np.testing.assert_allclose(contact, 0.0, atol=1e-9)
    code = main(["compensate", str(path), str(data), "--orientation", "qx,qy,qz,qw", "--g", "9.81",
                 "-o", str(tmp_path / "d.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and "--g" in err[-1] and not (tmp_path / "d.csv").exists()


@pytest.mark.parametrize("spec", ["tool:1e9", "tool:2@1e6,0,0"])
def test_absurd_load_specs_are_refused(spec):
    with pytest.raises(FtcalError):
        parse_payload_spec(spec)


def test_time_in_nanoseconds_is_refused_saying_so(tmp_path, capsys):
    """A bag's clock in ns (steps of 1e7 at 100 Hz) would read as 2e8 minutes of drift."""
    rot = Rotation.random(4, random_state=5)
    q = np.repeat(rot.as_quat(), 100, axis=0)
    g = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])
    wrench = np.c_[1.5 * g, np.cross([0.0, 0.01, 0.05], 1.5 * g)] + [1.0, -2.0, 0.5, 0.1, 0.0, -0.1]
    frame = pd.DataFrame(np.c_[wrench, q], columns=["u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"])
    frame["t"] = 1.7e18 + np.arange(400) * 1e7  # ns since 1970, 100 Hz
    frame.to_csv(tmp_path / "ns.csv", index=False)
    code = main(["payload", str(tmp_path / "ns.csv"), "--orientation", "qx,qy,qz,qw", "--time", "t",
                 "-o", str(tmp_path / "p.json")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "nanoseconds" in err[0] and not (tmp_path / "p.json").exists()
