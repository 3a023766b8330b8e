"""Robot-logger .mat files, v7.3 (HDF5) and v5, written here with h5py / scipy."""

import h5py
import numpy as np
import pytest
import scipy.io

from ftcal.data.logs import read_recording
from ftcal.runtime.errors import FtcalError

JOINTS = ["shoulder", "elbow"]


def write_v73(path, tree):
    """A MATLAB v7.3 file: HDF5 with a 512-byte header, arrays with reversed axes."""
    with h5py.File(path, "w", userblock_size=512) as f:
        refs = f.create_group("#refs#")

        def put(parent, name, node):
            if isinstance(node, dict):
                group = parent.create_group(name)
                group.attrs["MATLAB_class"] = np.bytes_("struct")
                for key, value in node.items():
                    put(group, key, value)
            elif isinstance(node, list):  # cell array of strings, MATLAB J x 1
                targets = []
                for text in node:
                    ds = refs.create_dataset(f"r{len(refs)}", data=np.array([[ord(c)] for c in text], np.uint16))
                    ds.attrs["MATLAB_class"] = np.bytes_("char")
                    targets.append(ds.ref)
                cell = parent.create_dataset(name, data=np.array([targets], dtype=h5py.ref_dtype))
                cell.attrs["MATLAB_class"] = np.bytes_("cell")
            else:
                ds = parent.create_dataset(name, data=np.asarray(node, dtype=float).T)
                ds.attrs["MATLAB_class"] = np.bytes_("double")

        put(f, "robot_logger_device", tree)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    header = header.ljust(116, b" ") + b"\0" * 8 + b"\x00\x02" + b"IM"
    with open(path, "r+b") as fh:
        fh.write(header)
    return path


def write_v5(path, tree):
    def convert(node):
        if isinstance(node, dict):
            return {k: convert(v) for k, v in node.items()}
        if isinstance(node, list):
            cell = np.empty((len(node), 1), dtype=object)
            cell[:, 0] = node
            return cell
        return np.asarray(node, dtype=float)

    scipy.io.savemat(path, {"robot_logger_device": convert(tree)})
    return path


def logger_tree(ft, temp, q, t_ft, t_q, *, names=("r_arm_ft",), layout="samples_first", joints=JOINTS,
                velocities=None, imu=None):
    """The logger struct in MATLAB orientation: samples × k or k × 1 × samples."""
    def shaped(x):
        x = np.asarray(x, float).reshape(len(x), -1)
        return x if layout == "samples_first" else x.T[:, None, :]

    tree = {"FTs": {n: {"data": shaped(ft), "timestamps": t_ft[:, None]} for n in names},
            "temperatures": {n: {"data": shaped(temp), "timestamps": t_ft[:, None]} for n in names},
            "joints_state": {"positions": {"data": shaped(q), "timestamps": t_q[:, None]}},
            "description_list": list(joints)}
    if velocities is not None:
        tree["joints_state"]["velocities"] = {"data": shaped(velocities), "timestamps": t_q[:, None]}
    if imu is not None:
        tree["accelerometers"] = {"imu": {"data": shaped(imu[0]), "timestamps": t_q[:, None]}}
        tree["gyros"] = {"imu": {"data": shaped(imu[1]), "timestamps": t_q[:, None]}}
    return tree


@pytest.fixture
def signals():
    rng = np.random.default_rng(5)
    n_ft, n_q = 40, 25
    return dict(ft=rng.normal(size=(n_ft, 6)), temp=np.linspace(30, 31, n_ft), q=rng.normal(size=(n_q, 2)),
                t_ft=100.0 + np.arange(n_ft) * 0.01, t_q=100.002 + np.arange(n_q) * 0.016)


@pytest.mark.parametrize("writer", [write_v73, write_v5])
@pytest.mark.parametrize("layout", ["samples_first", "channels_first"])
@pytest.mark.parametrize("name", ["r_arm_ft", "r_arm_ft_sensor"])
def test_read_logger_layouts(tmp_path, signals, writer, layout, name):
    s = signals
    path = writer(tmp_path / "rec.mat", logger_tree(s["ft"], s["temp"], s["q"], s["t_ft"], s["t_q"],
                                                    names=(name,), layout=layout,
                                                    velocities=2 * s["q"]))
    rec = read_recording(path)
    ft = rec.ft_stream("r_arm_ft", "r_arm_ft_sensor")  # either naming style finds it
    np.testing.assert_array_equal(ft.data, s["ft"])
    np.testing.assert_array_equal(ft.time, s["t_ft"])
    np.testing.assert_array_equal(rec.temperature_stream("r_arm_ft_sensor").data[:, 0], s["temp"])
    assert rec.joints.columns == tuple(JOINTS)
    np.testing.assert_array_equal(rec.joints.data, s["q"])
    np.testing.assert_array_equal(rec.joint_velocities.data, 2 * s["q"])
    assert rec.joint_accelerations is None


def test_degrees_and_imu(tmp_path, signals):
    s = signals
    acc, gyro = np.ones((25, 3)), np.zeros((25, 3))
    path = write_v73(tmp_path / "rec.mat", logger_tree(s["ft"], s["temp"], 180 * s["q"], s["t_ft"], s["t_q"],
                                                       imu=(acc, gyro), layout="channels_first"))
    rec = read_recording(path, joint_units="deg")
    np.testing.assert_allclose(rec.joints.data, np.pi * s["q"])
    np.testing.assert_array_equal(rec.accelerometers["imu"].data, acc)


def test_truncated_and_foreign_files(tmp_path, signals):
    s = signals
    for writer in (write_v73, write_v5):
        path = writer(tmp_path / f"{writer.__name__}.mat",
                      logger_tree(s["ft"], s["temp"], s["q"], s["t_ft"], s["t_q"]))
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        with pytest.raises(FtcalError, match=f"{writer.__name__}.mat: (cannot read|the MATLAB file is truncated)"):
            read_recording(path)
    junk = tmp_path / "junk.mat"
    junk.write_bytes(b"not a mat file at all" * 10)
    with pytest.raises(FtcalError, match="junk.mat: not a MATLAB v5 or v7.3 MAT-file"):
        read_recording(junk)
    with pytest.raises(FtcalError, match="no such file"):
        read_recording(tmp_path / "missing.mat")


def test_layout_errors(tmp_path, signals):
    s = signals
    tree = logger_tree(s["ft"], s["temp"], s["q"], s["t_ft"], s["t_q"])
    del tree["description_list"]
    with pytest.raises(FtcalError, match="description_list"):
        read_recording(write_v73(tmp_path / "a.mat", tree))
    tree = logger_tree(s["ft"][:-3], s["temp"], s["q"], s["t_ft"], s["t_q"])
    with pytest.raises(FtcalError, match=r"FTs.r_arm_ft.data has shape \(37, 6\).*40 samples"):
        read_recording(write_v5(tmp_path / "b.mat", tree))
    tree = logger_tree(s["ft"], s["temp"], s["q"], s["t_ft"], s["t_q"], joints=["a", "b", "c"])
    with pytest.raises(FtcalError, match="joints_state.positions.data"):
        read_recording(write_v73(tmp_path / "c.mat", tree))
    rec = read_recording(write_v5(tmp_path / "d.mat", logger_tree(s["ft"], s["temp"], s["q"], s["t_ft"], s["t_q"])))
    with pytest.raises(FtcalError, match="no F/T stream for sensor 'l_arm_ft' \\(FTs has: r_arm_ft\\)"):
        rec.ft_stream("l_arm_ft")
    with h5py.File(tmp_path / "e.mat", "w") as f:
        f.create_dataset("something_else", data=np.zeros(3))
    with pytest.raises(FtcalError, match="no 'robot_logger_device' struct"):
        read_recording(tmp_path / "e.mat")


def test_reads_the_simulator_writer(tmp_path):
    """Another writer in the project (ftcal.sim) produces files this reader accepts."""
    logger = pytest.importorskip("ftcal.sim.logger_mat")
    t = 5.0 + np.arange(30) * 0.01
    ft = np.arange(180.0).reshape(30, 6)
    log = logger.RobotLog(ft={"l_arm_ft_sensor": logger.Stream(t, ft)},
                          temperatures={"l_arm_ft_sensor": logger.Stream(t, np.full(30, 33.0))},
                          joint_names=("a", "b"), positions=logger.Stream(t, np.ones((30, 2))))
    for version in ("7.3", "5"):
        path = logger.write_robot_log(tmp_path / f"sim{version}.mat", log, version=version)
        rec = read_recording(path)
        np.testing.assert_array_equal(rec.ft_stream("l_arm_ft").data, ft)
        assert rec.joints.columns == ("a", "b")
