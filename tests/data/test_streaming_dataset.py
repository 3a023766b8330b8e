"""`ftcal dataset` with one Dask task per recording (a real LocalCluster): same table, same warnings."""

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_insitu import expected_at, make_recording
from test_logs_mat import write_v5, write_v73
from test_robot_model import TINY_URDF

from ftcal.insitu.recordings import InsituOptions, recordings_dataset as build_dataset
from ftcal.robot import RobotModel, load_case_config
from ftcal.runtime.errors import FtcalWarning
from ftcal.runtime.executors import open_executor

PAYLOAD = (2.0, np.array([0.1, 0.0, 0.0]))
# raw = 100 + 3·wrench: a HIGH limit of 100 reads every channel with a positive wrench as saturated
SATURATING = InsituOptions(savgol_frame=None, adc_limits=(-1e9, 100.0), cache=False)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dataset")
    a, b = folder / "l0kg-r0kg" / "grid.mat", folder / "l0kg-r2kg" / "grid.mat"
    t_a = make_recording(a, write_v73)[0]
    t_b = make_recording(b, write_v5, payload=PAYLOAD, layout="channels_first")[0]
    loads = folder / "loads.toml"
    loads.write_text('[convention.right]\nframe = "forearm"\ncom = [0.1, 0.0, 0.0]\n')
    return folder, [a, b], (t_a, t_b), loads


def build(recordings, executor):
    _, paths, _, loads = recordings
    tiny = RobotModel.from_text(TINY_URDF, "tiny.urdf")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = build_dataset(paths, tiny, "arm_ft", load_cases=load_case_config(loads), options=SATURATING,
                           executor=executor)
    return ds, [(str(w.message), w.category) for w in caught]


def test_a_cluster_builds_the_local_table_and_reports_its_warnings_in_order(recordings):
    here, here_warnings = build(recordings, None)
    with open_executor("local:2") as cluster:
        there, there_warnings = build(recordings, cluster)
    t_a, t_b = recordings[2]
    # against the hand-computed expected wrench of each load case
    np.testing.assert_allclose(there.outputs[:len(t_a)], expected_at(t_a), atol=1e-9)
    np.testing.assert_allclose(there.outputs[len(t_a):], expected_at(t_b, PAYLOAD), atol=1e-9)
    np.testing.assert_allclose(there.inputs, here.inputs, rtol=1e-12, atol=0)
    np.testing.assert_allclose(there.outputs, here.outputs, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(there.segments, here.segments)
    np.testing.assert_array_equal(there.groups, here.groups)
    assert there.sources == here.sources
    saturated = [w for w in here_warnings if issubclass(w[1], FtcalWarning)]
    assert len(saturated) >= 2 and all("saturated" in text for text, _ in saturated)
    assert there_warnings == saturated


def test_cli_bad_scheduler_is_one_line_and_writes_nothing(recordings):
    folder, paths, _, _ = recordings
    urdf = folder / "tiny.urdf"
    urdf.write_text(TINY_URDF)
    out = folder / "out.parquet"
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    done = subprocess.run([ftcal, "dataset", *map(str, paths), "--urdf", str(urdf), "--sensor", "arm_ft",
                           "--scheduler", "local:0", "-o", str(out)], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "--scheduler local:0" in done.stderr
    assert not out.exists()


def test_cli_expected_on_a_cluster_matches_the_hand_computed_wrench(recordings):
    import pandas as pd
    from test_robot_expected import FOREARM, static_wrench

    folder = recordings[0]
    urdf = folder / "tiny.urdf"
    urdf.write_text(TINY_URDF)
    angles = np.linspace(-1.0, 1.0, 7)
    joints = folder / "joints.csv"
    pd.DataFrame({"time": np.arange(7) * 0.1, "shoulder": angles}).to_csv(joints, index=False)
    out = folder / "expected.csv"
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    done = subprocess.run([ftcal, "expected", "--urdf", str(urdf), "--joints", str(joints), "--sensor", "arm_ft",
                           "--scheduler", "local:1", "--no-cache", "-o", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(out)
    wrench = table[[f"arm_ft_{n}" for n in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")]].to_numpy()
    np.testing.assert_allclose(wrench, [static_wrench([FOREARM], a) for a in angles], atol=1e-9)
    np.testing.assert_array_equal(table["time"], np.arange(7) * 0.1)
