"""Static holds of robot-log datasets (``ftcal dataset`` on .mat logs): the ``static`` and ``hold`` columns
against a simulated hold-and-move schedule, ``fit --group-by hold`` and ``payload`` on the table.

Truth: the joint follows a schedule written here (holds, minimum-jerk moves between them), logged on
its own clock beside the F/T stream; the reading is the tiny robot's expected wrench, worked out by
hand in test_robot_expected, plus a bias and noise."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from test_logs_mat import logger_tree, write_v5, write_v73
from test_robot_expected import FOREARM, static_wrench
from test_robot_model import TINY_URDF

from ftcal.cli import main
from ftcal.data.holds import find_holds, number_across
from ftcal.runtime.errors import FtcalWarning

FT_RATE, Q_RATE = 100.0, 62.5
HOLD_S, MOVE_S = 1.2, 1.0
T0 = 50.0  # the logger's clock at the start of the schedule
BIAS = np.array([0.5, -0.3, 0.8, 0.02, -0.01, 0.03])


def schedule(poses, t):
    """Joint angle (rad) at times ``t`` (s from the start): hold each pose, then a minimum-jerk move."""
    period = HOLD_S + MOVE_S
    k = np.minimum((t // period).astype(int), len(poses) - 1)
    phase = np.clip((t - k * period - HOLD_S) / MOVE_S, 0.0, 1.0)
    nxt = np.minimum(k + 1, len(poses) - 1)
    return poses[k] + phase ** 3 * (10 - 15 * phase + 6 * phase ** 2) * (poses[nxt] - poses[k])


def true_holds(poses):
    """(first, last) time of each simulated hold."""
    period = HOLD_S + MOVE_S
    return [(j * period, j * period + HOLD_S) for j in range(len(poses))]


def write_log(path, writer, poses, seed, t0=None):
    """A .mat log: F/T at 100 Hz, the joint at 62.5 Hz from a little later; returns (t_ft, hold index)."""
    t0 = T0 if t0 is None else t0
    rng = np.random.default_rng(seed)
    span = len(poses) * (HOLD_S + MOVE_S) - MOVE_S
    t_ft = np.arange(int(span * FT_RATE) + 1) / FT_RATE
    t_q = 0.004 + np.arange(int((span - 0.01) * Q_RATE) + 1) / Q_RATE
    wrench = np.array([static_wrench([FOREARM], q) for q in schedule(poses, t_ft)])
    raw = wrench + BIAS + 0.01 * rng.normal(size=wrench.shape)
    temp = 30.0 + 0.1 * rng.normal(size=t_ft.size)
    path.parent.mkdir(parents=True, exist_ok=True)
    writer(path, logger_tree(raw, temp, schedule(poses, t_q)[:, None], t0 + t_ft, t0 + t_q,
                             names=("arm_ft_sensor",), joints=["shoulder"]))
    return t_ft


POSES = [np.array([0.0, 0.6, -0.5, 1.1, 0.2]), np.array([-0.8, 0.3, 0.9, -0.2])]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    root = tmp_path_factory.mktemp("logs")
    (root / "tiny.urdf").write_text(TINY_URDF)
    paths = [root / "a.mat", root / "b.mat"]
    times = [write_log(paths[0], write_v73, POSES[0], 1), write_log(paths[1], write_v5, POSES[1], 2)]
    return root, paths, times


def dataset(capsys, root, paths, out):
    assert main(["dataset", *map(str, paths), "--urdf", str(root / "tiny.urdf"), "--sensor", "arm_ft",
                 "--no-filter", "--no-cache", "-o", str(out)]) == 0
    return capsys.readouterr().out


def test_log_dataset_marks_the_simulated_holds(logs, capsys):
    root, paths, times = logs
    out = dataset(capsys, root, paths, root / "data.parquet")
    frame = pd.read_parquet(root / "data.parquet")
    assert {"time", "shoulder", "static", "hold"} <= set(frame.columns)
    assert "9 static hold(s)" in out and "samples moving (from the joints)" in out
    first = 0
    for segment, poses in enumerate(POSES):
        part = frame[frame["segment"] == segment]
        rel = part["time"].to_numpy() - T0  # s from the simulated start
        static, hold = part["static"].to_numpy() == 1, part["hold"].to_numpy()
        assert np.all(hold[~static] == -1) and np.all(hold[static] >= 0)
        numbers = sorted(set(hold[static]))
        assert numbers == list(range(first, first + len(poses)))  # counted on from the previous recording
        for j, (begin, end) in enumerate(true_holds(poses)):
            rows = np.flatnonzero(hold == first + j)
            # the hold's own samples, give or take the slowest instants of a minimum-jerk move (6 samples)
            assert abs(rel[rows[0]] - max(begin, rel[0])) <= 0.06 and abs(rel[rows[-1]] - min(end, rel[-1])) <= 0.06
            assert rows[-1] - rows[0] + 1 == rows.size  # one run
        # every sample in the middle of a move is marked moving
        period = HOLD_S + MOVE_S
        into_move = (rel % period) - HOLD_S
        mid_move = (into_move > 0.1) & (into_move < MOVE_S - 0.1) & (rel < (len(poses) - 1) * period)
        assert mid_move.any() and not static[mid_move].any()
        first += len(poses)


def test_fit_groups_by_pose_and_payload_drops_the_moves(logs, capsys):
    root, paths, _ = logs
    table = root / "fit.parquet"
    dataset(capsys, root, paths, table)
    frame = pd.read_parquet(table)
    n_poses = sum(len(p) for p in POSES)
    # one group per pose, plus the moves (hold -1): the fit's folds
    with warnings.catch_warnings():  # one joint turning about x: gravity in a plane, which the fit says
        warnings.simplefilter("always", FtcalWarning)
        assert main(["fit", str(table), "--group-by", "hold", "--degree", "auto", "--max-degree", "1",
                     "--folds", "50", "-o", str(root / "m.json")]) == 0
    captured = capsys.readouterr()
    assert f"x {n_poses + 1} folds" in captured.out and "warning: reference wrenches span 2 of 6" in captured.err
    # payload on the same table through the joints: the moves are excluded, the forearm's mass comes out
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["payload", str(table), "--urdf", str(root / "tiny.urdf"), "--sensor", "arm_ft",
                     "--group-by", "hold", "-o", str(root / "p.json")]) == 0
    out = capsys.readouterr().out
    n_moving = int((frame["static"] == 0).sum())
    assert f"{n_moving} of " in out and "from the joints" in out and "excluded" in out
    assert f"in {n_poses} group(s)" in out
    doc = json.loads((root / "p.json").read_text())
    assert doc["mass"] == pytest.approx(FOREARM[0], abs=5 * doc["stderr"]["mass"])


def test_joints_decide_the_holds_not_the_log_clock():
    """A log timed at another rate gives the same holds: time comes from the stamps, not a fixed rate."""
    t = np.arange(int(10.0 * 250)) / 250.0
    poses = np.array([0.1, 0.9, -0.4, 0.3, 0.0])
    a = find_holds(t, joints=schedule(poses, t)[:, None])
    t2 = t[::5]
    b = find_holds(t2, joints=schedule(poses, t2)[:, None])
    assert a.n_holds == b.n_holds == 5
    np.testing.assert_allclose(t[a.ranges()[0]], t2[b.ranges()[0]], atol=0.05)


def test_number_across_recordings():
    # hand-numbered: the second recording's holds follow the first's; one without holds takes no number
    got = number_across([np.array([-1, 0, 0, -1, 1]), np.array([-1, -1]), np.array([0, -1, 1, 1])])
    np.testing.assert_array_equal(got, [-1, 0, 0, -1, 1, -1, -1, 2, -1, 3, 3])
