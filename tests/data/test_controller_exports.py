"""``convert --to admittance-controller | gravity-compensation-filter | ur-payload``: the keys are the upstream
parameter definitions' (cited in ftcal.files.controller_formats), and each controller's own compensation formula, fed
these files' values, removes a simulated tool's gravity wrench in any orientation."""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml

from ftcal.cli import main
from ftcal.files.payload_json import save_payload
from ftcal.payload.parameters import PayloadParameters

MASS, COM, G = 1.37, np.array([0.012, -0.004, 0.083]), 9.81


def payload(tmp_path, reaction=False, frame="ft_sensor"):
    path = tmp_path / "tool.json"
    save_payload(PayloadParameters(MASS, COM, np.zeros(3), np.zeros(3), G, frame=frame, reaction=reaction,
                                   stderr={"mass": 1e-3, "com": np.full(3, 1e-4), "force_bias": np.full(3, .01),
                                           "torque_bias": np.full(3, 1e-3)},
                                   fit={"n_samples": 100, "residual_rms": np.full(6, 0.05), "condition_number": 1.0,
                                        "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]}),
                 path)
    return path


def convert(tmp_path, target, name, *extra):
    out = tmp_path / name
    assert main(["convert", str(payload(tmp_path)), "--to", target, "-o", str(out), *extra]) == 0
    return out


def readings(n=50, seed=4):
    """The tool hanging on a sensor in random orientations (R: sensor to world), ftcal's convention: F = m g_s."""
    from scipy.spatial.transform import Rotation

    rotations = Rotation.random(n, random_state=seed).as_matrix()
    force = np.einsum("kji,j->ki", rotations, [0.0, 0.0, -MASS * G])  # R^T m g
    return rotations, force, np.cross(COM, force)


def test_admittance_controller_parameters_remove_the_tools_weight(tmp_path):
    doc = yaml.safe_load(convert(tmp_path, "admittance-controller", "admittance.yaml").read_text())
    gc = doc["admittance_controller"]["ros__parameters"]["gravity_compensation"]
    # admittance_controller_parameters.yaml: gravity_compensation.frame.id, .CoG.pos (3), .CoG.force (= m * 9.81)
    assert set(gc) == {"frame", "CoG"} and set(gc["frame"]) == {"id"} and set(gc["CoG"]) == {"pos", "force"}
    assert gc["frame"]["id"] == "ft_sensor" and len(gc["CoG"]["pos"]) == 3
    # admittance_rule_impl.hpp: in the base frame, wrench -= (0, 0, -force), torque -= (R pos) x (0, 0, -force)
    weight = np.array([0.0, 0.0, -gc["CoG"]["force"]])
    for R, f, t in zip(*readings()):
        f_base, t_base = R @ f - weight, R @ t - np.cross(R @ np.array(gc["CoG"]["pos"]), weight)
        np.testing.assert_allclose(np.r_[f_base, t_base], 0.0, atol=1e-9)


def test_gravity_compensation_filter_parameters_remove_the_tools_weight(tmp_path):
    doc = yaml.safe_load(convert(tmp_path, "gravity-compensation-filter", "filter.yaml", "--world-frame",
                                 "base_link").read_text())
    p = doc["/**"]["ros__parameters"]
    # gravity_compensation_filter_parameters.yaml: world_frame, sensor_frame, tool.CoG (3), tool.mass, tool.gravity_field
    assert set(p) == {"world_frame", "sensor_frame", "tool"} and set(p["tool"]) == {"CoG", "mass", "gravity_field"}
    assert (p["world_frame"], p["sensor_frame"]) == ("base_link", "ft_sensor")
    # gravity_compensation.cpp: F -= mass * gravity_field rotated into the sensor frame; T -= CoG x that force
    for R, f, t in zip(*readings()):
        g_s = R.T @ (p["tool"]["mass"] * np.array(p["tool"]["gravity_field"]))
        np.testing.assert_allclose(np.r_[f - g_s, t - np.cross(p["tool"]["CoG"], g_s)], 0.0, atol=1e-9)


def test_ur_payload_is_urscripts_set_payload_and_the_drivers_service(tmp_path):
    text = convert(tmp_path, "ur-payload", "payload.script").read_text()
    call = re.search(r"^set_payload\(([^,]+), \[([^\]]+)\]\)$", text, re.M)
    assert float(call.group(1)) == MASS and [float(v) for v in call.group(2).split(",")] == COM.tolist()
    service = re.search(r"ur_msgs/srv/SetPayload \"(.*)\"$", text, re.M).group(1)
    request = yaml.safe_load(service)  # SetPayload.srv: float32 mass, geometry_msgs/Vector3 center_of_gravity
    assert request["mass"] == MASS and [request["center_of_gravity"][k] for k in "xyz"] == COM.tolist()


@pytest.mark.parametrize("target", ["admittance-controller", "gravity-compensation-filter", "ur-payload"])
def test_a_reaction_payload_is_refused_in_one_line(tmp_path, target, capsys):
    path = payload(tmp_path, reaction=True)
    assert main(["convert", str(path), "--to", target, "-o", str(tmp_path / "out.yaml" if "ur" not in target
                                                                       else tmp_path / "out.script")]) == 2
    assert "--reaction" in capsys.readouterr().err and not list(tmp_path.glob("out.*"))
