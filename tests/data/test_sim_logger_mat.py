"""Robot-logger .mat files: MATLAB v7.3 (HDF5) and v5 layouts as documented."""

import h5py
import numpy as np
import pytest
import scipy.io

from ftcal.runtime.errors import FtcalError
from ftcal.sim.logger_mat import RobotLog, Stream, write_robot_log

N_FT, N_Q = 7, 5
JOINTS = ("torso_pitch", "r_shoulder_pitch", "r_elbow")


@pytest.fixture
def log():
    rng = np.random.default_rng(0)
    t_ft = 10.0 + np.arange(N_FT) * 0.01
    t_q = 10.003 + np.arange(N_Q) * 0.01
    return RobotLog(ft={"r_arm_ft": Stream(t_ft, rng.normal(size=(N_FT, 6)))},
                    temperatures={"r_arm_ft": Stream(t_ft + 0.001, np.linspace(30, 31, N_FT))},
                    joint_names=JOINTS,
                    positions=Stream(t_q, rng.normal(size=(N_Q, 3))),
                    velocities=Stream(t_q, rng.normal(size=(N_Q, 3))),
                    robot_name="iCubGenova11")


def _decode(f, ref):
    return "".join(chr(c[0]) for c in f[ref])


def test_v73_header_and_userblock(tmp_path, log):
    path = write_robot_log(tmp_path / "rec.mat", log)
    head = path.read_bytes()[:128]
    assert head.startswith(b"MATLAB 7.3 MAT-file")
    assert head[124:126] == b"\x00\x02" and head[126:128] == b"IM"
    with h5py.File(path, "r") as f:
        assert f.userblock_size == 512


def test_v73_channels_first_layout(tmp_path, log):
    path = write_robot_log(tmp_path / "rec.mat", log)
    with h5py.File(path, "r") as f:
        root = f["robot_logger_device"]
        assert root.attrs["MATLAB_class"] == b"struct"
        ft = root["FTs/r_arm_ft/data"]
        # MATLAB 6 x 1 x N, column-major: element (c, 1, k) sits at HDF5 [k, 0, c].
        assert ft.shape == (N_FT, 1, 6)
        assert ft.attrs["MATLAB_class"] == b"double"
        assert np.array_equal(ft[:, 0, :], log.ft["r_arm_ft"].data)
        assert np.array_equal(np.squeeze(root["FTs/r_arm_ft/timestamps"][()]), log.ft["r_arm_ft"].timestamps)
        assert root["temperatures/r_arm_ft/data"].shape == (N_FT, 1, 1)
        assert root["joints_state/positions/data"].shape == (N_Q, 1, 3)
        assert np.array_equal(root["joints_state/velocities/data"][:, 0, :], log.velocities.data)
        assert "accelerations" not in root["joints_state"]
        names = root["description_list"]
        assert names.attrs["MATLAB_class"] == b"cell" and names.shape == (1, 3)
        assert tuple(_decode(f, r) for r in names[0]) == JOINTS
        first = f[names[0][0]]
        assert first.attrs["MATLAB_class"] == b"char" and first.shape == (len(JOINTS[0]), 1)
        assert "".join(map(chr, root["yarp_robot_name"][:, 0])) == "iCubGenova11"


def test_v73_samples_first_layout(tmp_path, log):
    path = write_robot_log(tmp_path / "rec.mat", log, layout="samples_first")
    with h5py.File(path, "r") as f:
        ft = f["robot_logger_device/FTs/r_arm_ft/data"]
        assert ft.shape == (6, N_FT)  # MATLAB N x 6, transposed
        assert np.array_equal(ft[()].T, log.ft["r_arm_ft"].data)


@pytest.mark.parametrize("layout,shape", [("samples_first", (N_FT, 6)), ("channels_first", (6, 1, N_FT))])
def test_v5_is_readable_by_scipy(tmp_path, log, layout, shape):
    path = write_robot_log(tmp_path / "rec.mat", log, version="5", layout=layout)
    root = scipy.io.loadmat(path, simplify_cells=True)["robot_logger_device"]
    # Unsqueezed, to see the stored MATLAB dimensions.
    raw = scipy.io.loadmat(path, struct_as_record=False)["robot_logger_device"][0, 0]
    assert raw.FTs[0, 0].r_arm_ft[0, 0].data.shape == shape
    data = raw.FTs[0, 0].r_arm_ft[0, 0].data
    flat = data if layout == "samples_first" else data[:, 0, :].T
    assert np.array_equal(flat, log.ft["r_arm_ft"].data)
    assert tuple(root["description_list"]) == JOINTS
    assert np.allclose(root["temperatures"]["r_arm_ft"]["timestamps"], log.temperatures["r_arm_ft"].timestamps)


def test_mismatched_streams_are_rejected(log):
    with pytest.raises(FtcalError, match="6 channels"):
        RobotLog({"r_arm_ft": Stream(np.zeros(3), np.zeros((3, 5)))}, {}, JOINTS, log.positions)
    with pytest.raises(FtcalError, match="3 joint names"):
        RobotLog({}, {}, JOINTS, Stream(np.zeros(3), np.zeros((3, 2))))
    with pytest.raises(FtcalError, match="timestamps of shape"):
        Stream(np.zeros(3), np.zeros((4, 2)))


def test_bad_version_is_rejected(tmp_path, log):
    with pytest.raises(FtcalError, match="'version' parameter"):
        write_robot_log(tmp_path / "rec.mat", log, version="7")
