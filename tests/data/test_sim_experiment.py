"""The simulated paper experiment: folders, manifest, streams on their own clocks."""

import json

import h5py
import numpy as np
import pytest

from ftcal.sim.experiment import ExperimentConfig, folder_name, run_experiment

GRAVITY = 9.81


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    folder = tmp_path_factory.mktemp("exp")
    config = ExperimentConfig(loads_kg=(0.0, 10.0), temperatures=(30.0,), trajectories=("grid",), seed=1)
    files, manifest = run_experiment(folder, config)
    return folder, config, files, manifest


def test_paper_folder_naming():
    assert folder_name(0, 5) == "l0kg-r5kg"
    assert folder_name(2.5, 0) == "l2.5kg-r0kg"


def test_files_and_manifest(experiment):
    folder, config, files, manifest = experiment
    assert [f.relative_to(folder).as_posix() for f in files] == [
        "l0kg-r0kg/grid_30C.mat", "l0kg-r10kg/grid_30C.mat"]
    document = json.loads((folder / "manifest.json").read_text())
    assert [r["file"] for r in document["recordings"]] == [m.file for m in manifest]
    assert manifest[0].payloads == ("r_forearm:0.6@-0.09,0,0.03",)
    assert manifest[1].payloads[1] == "r_forearm:10@-0.09,0,0.03"
    for m in manifest:
        # The sensor warms towards start + 1..3 degC, slowly.
        assert m.temperature_start == 30.0 and 30.0 < m.temperature_end < 33.0


def test_streams_have_their_own_clocks(experiment):
    _, config, files, manifest = experiment
    with h5py.File(files[0], "r") as f:
        root = f["robot_logger_device"]
        t_ft = np.squeeze(root["FTs/r_arm_ft/timestamps"][()])
        t_q = np.squeeze(root["joints_state/positions/timestamps"][()])
        t_temp = np.squeeze(root["temperatures/r_arm_ft/timestamps"][()])
        # Epoch-sized timestamps (1.7e9 s) resolve about 0.2 us in double precision.
        assert np.allclose(np.diff(t_ft), 1 / config.ft_rate, rtol=0, atol=1e-6)
        assert np.allclose(np.diff(t_temp), 1 / config.temperature_rate, rtol=0, atol=1e-6)
        assert t_q[0] - t_ft[0] == pytest.approx(config.joint_delay, abs=1e-6)
        assert root["FTs/r_arm_ft/data"].shape == (manifest[0].n_samples, 1, 6)
        names = ["".join(chr(c[0]) for c in f[r]) for r in root["description_list"][0]]
        assert root["joints_state/positions/data"].shape == (len(t_q), 1, len(names))
        assert "r_elbow" in names and "torso_pitch" in names


def test_raw_force_follows_the_added_weight(experiment):
    _, config, files, _ = experiment
    norms = []
    for path in files:
        with h5py.File(path, "r") as f:
            data = f["robot_logger_device/FTs/r_arm_ft/data"][:, 0, :]
        norms.append(np.median(np.linalg.norm(data[:, :3], axis=1)))
    # 10 kg more on the forearm: ~98 N more, within the sensor's gain errors (20 %).
    assert norms[1] - norms[0] == pytest.approx(10.0 * GRAVITY, rel=0.2)
