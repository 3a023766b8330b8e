"""Static holds (ftcal.data.holds) and their use: payload on static samples only, dataset columns, the
/joint_states route from a bag to a payload. Truth from the simulations (hold times, mass, COM)."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from bag_data import Bag
from scipy.spatial.transform import Rotation

from ftcal.check.conventions import read_holds
from ftcal.cli import main
from ftcal.data.holds import MIN_HOLD_S, Holds, find_holds, hold_averages
from ftcal.payload.kinematics import OrientationSource
from ftcal.runtime.errors import FtcalError, FtcalWarning

T0 = 1_700_000_000 * 10**9
WRENCH = ["u1", "u2", "u3", "u4", "u5", "u6"]


def minimum_jerk(phase):
    return phase ** 3 * (10 - 15 * phase + 6 * phase ** 2)


def hold_and_move(n_poses, hold_s, move_s, rate):
    """Time, pose index k and blend (0 still at pose k, rising to 1 at pose k + 1) of a hold-move schedule."""
    period = hold_s + move_s
    t = np.arange(int((n_poses * period - move_s) * rate) + 1) / rate
    k = np.minimum((t // period).astype(int), n_poses - 1)
    phase = np.clip((t - k * period - hold_s) / move_s, 0.0, 1.0)
    return t, k, minimum_jerk(phase), (t - k * period) <= hold_s + 1e-9


def rotations(n_poses, seed):
    return Rotation.random(n_poses, random_state=seed)


def slerped(poses, k, blend):
    nxt = np.minimum(k + 1, len(poses) - 1)
    delta = (poses[k].inv() * poses[nxt]).as_rotvec()
    return poses[k] * Rotation.from_rotvec(delta * blend[:, None])


def test_orientation_holds_match_the_schedule():
    t, k, blend, still = hold_and_move(10, 1.0, 1.5, 200.0)
    holds = find_holds(t, orientation=slerped(rotations(10, 1), k, blend).as_quat())
    assert holds.n_holds == 10 and holds.signal == "orientation"
    # each hold is one pose, numbered in time order
    np.testing.assert_array_equal(np.unique(k[holds.static]), np.arange(10))
    for j in range(10):  # pose j, or the last instants of the move arriving there
        m = holds.hold == j
        assert np.all((k[m] == j) | ((k[m] == j - 1) & (blend[m] > 0.999)))
    # samples called still that move: only the first instants of a minimum-jerk move (below 0.01 rad/s)
    assert np.all(still[holds.static] | (np.minimum(blend, 1 - blend)[holds.static] < 1e-3))
    assert not np.any(holds.static[~still & (blend > 0.01) & (blend < 0.99)])
    assert np.all(holds.static[still])
    assert holds.n_moving == np.count_nonzero(~holds.static)
    line = holds.describe(t)
    assert f"{holds.n_moving} of {t.size} samples moving (from the orientation) in 9 stretch(es): rows " in line


def test_gravity_joints_and_wrench_signals():
    rng = np.random.default_rng(3)
    t, k, blend, still = hold_and_move(8, 0.8, 1.2, 100.0)
    rot = slerped(rotations(8, 2), k, blend)
    gravity = rot.inv().apply([0.0, 0.0, -9.81])
    assert find_holds(t, gravity=gravity).n_holds == 8
    # joints with encoder noise (1e-4 rad): noise is not motion
    targets = rng.uniform(-2, 2, (8, 6))
    nxt = np.minimum(k + 1, 7)
    q = targets[k] + blend[:, None] * (targets[nxt] - targets[k]) + rng.normal(0, 1e-4, (t.size, 6))
    holds = find_holds(t, joints=q)
    assert holds.n_holds == 8 and np.mean(holds.static == still) > 0.95
    # the wrench of a 2 kg tool plus noise, no kinematics: the rolling spread against the noise floor
    wrench = np.c_[2.0 * gravity, np.cross([0.0, 0.0, 0.1], 2.0 * gravity)]
    wrench += rng.normal(0, 1, wrench.shape) * [0.05, 0.05, 0.05, 0.002, 0.002, 0.002]
    holds = find_holds(t, wrench=wrench)
    assert holds.signal == "wrench variation" and np.mean(holds.static == still) > 0.9
    assert abs(holds.n_holds - 8) <= 1


def test_instant_jumps_keep_every_pose_whole_and_short_stops_are_not_holds():
    # a table of still poses, 30 samples each at 100 Hz, jumping between them: nothing moves
    t = np.arange(16 * 30) * 0.01
    q = np.repeat(rotations(16, 5).as_quat(), 30, axis=0)
    holds = find_holds(t, orientation=q)
    assert holds.n_moving == 0 and holds.n_holds == 16
    np.testing.assert_array_equal(holds.hold, np.repeat(np.arange(16), 30))
    # a stop shorter than MIN_HOLD_S inside a move is moving
    t = np.arange(300) * 0.01
    angle = np.clip(t - 0.5, 0, None) * 0.5  # turning at 0.5 rad/s after 0.5 s ...
    angle[150:150 + int(MIN_HOLD_S / 0.01) - 5] = angle[150]  # ... with a pause of just under MIN_HOLD_S
    angle[150 + int(MIN_HOLD_S / 0.01) - 5:] += angle[150] - angle[150 + int(MIN_HOLD_S / 0.01) - 5]
    holds = find_holds(t, orientation=Rotation.from_rotvec(np.c_[0 * t, 0 * t, angle]).as_quat())
    assert holds.n_holds == 1 and np.all(holds.hold[:50] == 0) and not holds.static[100:].any()
    # ... but a recording that never moves is one hold, however short (a file per pose)
    short = np.arange(5) * 0.01
    assert find_holds(short, orientation=np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))).n_holds == 1


def test_holds_stay_inside_segments_and_time_must_increase():
    t = np.r_[np.arange(100) * 0.01, np.arange(100) * 0.01]  # two recordings, each from t = 0
    q = np.tile([0.0, 0.0, 0.0, 1.0], (200, 1))
    holds = find_holds(t, orientation=q, segments=np.repeat([0, 1], 100))
    np.testing.assert_array_equal(holds.hold, np.repeat([0, 1], 100))
    with pytest.raises(FtcalError, match=r"run.csv: column 'stamp' does not increase at row 100; sort the table "
                                         r"by time \(or, for a ROS bag, rebuild it with receive_time\)"):
        find_holds(t, orientation=q, where="run.csv", time_column="stamp")
    with pytest.raises(FtcalError, match="no orientation, gravity, joint or wrench columns"):
        find_holds(t[:100])


# ---------------------------------------------------------------------------------------------- payload


@pytest.fixture(scope="module")
def moving_bag(tmp_path_factory):
    """The simulated arm, 60 % of the recording moving between holds (1 s still, 1.5 s moving)."""
    from ftcal.sim.arm_bag import ArmScenario, write_arm_bag

    root = tmp_path_factory.mktemp("moving")
    scenario = ArmScenario(force_bias_tc=(0.0, 0.0, 0.0), hold_s=1.0, move_s=1.5, n_poses=12, rate=100.0,
                           tf_rate=50.0, imu_rate=50.0)
    truth = write_arm_bag(root / "bag", scenario)
    table = root / "arm.parquet"
    assert main(["dataset", str(truth.path), "--wrench-topic", "/ft_sensor/wrench", "--tf", "base_link",
                 "--imu-topic", "/imu", "--no-filter", "-o", str(table)]) == 0
    return root, truth, table


def payload(capsys, table, out, *options):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        code = main(["payload", str(table), "--orientation", "qx,qy,qz,qw", "-o", str(out), *options])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured.out, json.loads(out.read_text())


def z_scores(doc, truth):
    return np.r_[(doc["mass"] - truth.mass) / doc["stderr"]["mass"],
                 (np.array(doc["com"]) - truth.com) / np.array(doc["stderr"]["com"])]


def test_dataset_marks_the_holds_of_the_simulated_arm(moving_bag, capsys):
    root, truth, table = moving_bag
    frame = pd.read_parquet(table)
    assert {"static", "hold"} <= set(frame.columns)
    t = frame["time"].to_numpy()
    still = np.zeros(len(t), bool)
    for begin, end in truth.holds:
        still |= (t >= begin - 1e-6) & (t <= end + 1e-6)
    assert still.mean() < 0.45  # most of the recording moves
    static = frame["static"].to_numpy() == 1
    assert np.all(static[still]) and np.mean(static == still) > 0.97
    assert sorted(set(frame.loc[static, "hold"])) == list(range(12))
    assert np.all(frame.loc[~static, "hold"] == -1)


def test_payload_excludes_the_moving_samples(moving_bag, capsys):
    root, truth, table = moving_bag
    out, doc = payload(capsys, table, root / "static.json", "--group-by", "hold")
    n_moving = int((pd.read_parquet(table)["static"] == 0).sum())
    assert "samples moving (from the orientation) in 11 stretch(es): rows " in out and "excluded" in out
    assert f"{n_moving} of {len(pd.read_parquet(table))} samples moving" in out
    assert "in 12 group(s)" in out  # one cross-validation group per pose, the moves left out
    assert np.all(np.abs(z_scores(doc, truth)) < 4), z_scores(doc, truth)
    # all samples: the moves' inertial wrench pulls the estimates many of the static fit's standard errors
    # away (its own, block-robust standard errors widen to cover part of that: they are not the yardstick)
    _, kept = payload(capsys, table, root / "all.json", "--keep-moving")
    pulled = np.r_[kept["mass"] - truth.mass, np.array(kept["com"]) - truth.com]
    static_se = np.r_[doc["stderr"]["mass"], doc["stderr"]["com"]]
    assert np.max(np.abs(pulled / static_se)) > 10, pulled / static_se
    # --dynamic is unchanged: it uses every sample
    out, _ = payload(capsys, table, root / "dynamic.json", "--dynamic")
    assert "static samples" not in out and f"payload from {len(pd.read_parquet(table))} samples" in out


def test_payload_without_static_holds_or_time(capsys, tmp_path):
    t = np.arange(400) * 0.01
    q = Rotation.from_rotvec(np.c_[0.3 * t, 0.2 * t, 0 * t]).as_quat()  # turning all the time
    gravity = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])
    frame = pd.DataFrame(np.c_[t, q, np.c_[gravity, np.cross([0, 0, 0.1], gravity)]],
                         columns=["time", "qx", "qy", "qz", "qw", *WRENCH])
    frame.to_csv(tmp_path / "moving.csv", index=False)
    out = tmp_path / "p.json"
    assert main(["payload", str(tmp_path / "moving.csv"), "--orientation", "qx,qy,qz,qw", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no static hold of 0.2 s or more" in err[0] and "--keep-moving" in err[0]
    assert not out.exists()
    q = rotations(400, 7).as_quat()  # a table of poses without a clock: used whole
    gravity = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])
    frame = pd.DataFrame(np.c_[q, np.c_[gravity, np.cross([0, 0, 0.1], gravity)]], columns=["qx", "qy", "qz", "qw",
                                                                                          *WRENCH])
    frame.to_csv(tmp_path / "untimed.csv", index=False)
    assert main(["payload", str(tmp_path / "untimed.csv"), "--orientation", "qx,qy,qz,qw", "-o", str(out)]) == 0
    assert "no time column 'time': all 400 samples used as static" in capsys.readouterr().out
    # without its clock, a table's own 'static' marks (from ftcal dataset) choose the samples: the second half
    # here carries a 5 N push, which only the marked-moving rows hold
    marked = frame.assign(static=np.r_[np.ones(200, int), np.zeros(200, int)])
    marked.loc[200:, "u1"] += 5.0
    marked.to_csv(tmp_path / "marked.csv", index=False)
    assert main(["payload", str(tmp_path / "marked.csv"), "--orientation", "qx,qy,qz,qw", "-o", str(out)]) == 0
    assert "its 'static' column marks 200 of 400 samples moving; excluded" in capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert doc["mass"] == pytest.approx(1.0, abs=1e-6) and doc["force_bias"][0] == pytest.approx(0.0, abs=1e-6)
    marked.assign(static=2).to_csv(tmp_path / "bad.csv", index=False)
    assert main(["payload", str(tmp_path / "bad.csv"), "--orientation", "qx,qy,qz,qw", "-o", str(out)]) == 2
    assert "column 'static' must hold 1 (still) or 0 (moving)" in capsys.readouterr().err


# ------------------------------------------------------------------------------ the /joint_states route


UR5_TOOL = {"mass": 1.6, "com": np.array([0.015, -0.01, 0.09]), "bias": np.array([3.0, -2.0, 5.0, 0.2, -0.1, 0.05])}
UR5_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]


@pytest.fixture(scope="module")
def ur5_bag(tmp_path_factory):
    """A UR5 holding 10 poses, moving between them: /ft and /joint_states only, no /tf."""
    from test_robot_declare import G_BASE, UR5, ur5_chain_rotation

    if not UR5.is_file():
        pytest.skip("example-robot-data is not installed")
    rng = np.random.default_rng(11)
    mass, com, bias = UR5_TOOL["mass"], UR5_TOOL["com"], UR5_TOOL["bias"]
    noise = np.array([0.05, 0.05, 0.05, 0.002, 0.002, 0.002])
    t, k, blend, still = hold_and_move(10, 0.6, 0.6, 50.0)
    targets = rng.uniform(-2.5, 2.5, (10, 6))
    q = targets[k] + blend[:, None] * (targets[np.minimum(k + 1, 9)] - targets[k])
    bump = np.where(still, 0.0, np.sin(np.pi * blend))  # the tool's inertial force while moving: up to 2 m/s²
    bag = Bag("mcap")
    for j in range(t.size):
        g_sensor = ur5_chain_rotation(q[j], "ee_link")[0].T @ G_BASE
        force = mass * (g_sensor - [2.0 * bump[j], 0.0, 0.0])
        wrench = np.r_[force, np.cross(com, force)] + bias + rng.normal(0.0, 1.0, 6) * noise
        stamp = T0 + int(round(t[j] * 1e9))
        bag.wrench("/ft", stamp, wrench)
        bag.joints("/joint_states", stamp, [*UR5_JOINTS, "gripper_finger"], [*q[j], np.nan])
    root = tmp_path_factory.mktemp("ur5")
    return bag.write(root / "ur5"), q, still, UR5


def test_bag_with_only_ft_and_joint_states_to_payload(ur5_bag, tmp_path, capsys):
    """dataset keeps the joint columns; payload --urdf finds the holds from the joints and recovers the tool."""
    path, q, still, ur5 = ur5_bag
    mass, com, bias = UR5_TOOL["mass"], UR5_TOOL["com"], UR5_TOOL["bias"]
    names = UR5_JOINTS
    table = tmp_path / "ur5.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["dataset", str(path), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                     "--no-filter", "-o", str(table)]) == 0
    assert "gripper_finger have non-finite positions; left out of the table" in capsys.readouterr().err
    frame = pd.read_csv(table)
    np.testing.assert_allclose(frame[names].to_numpy(), q, atol=1e-9)
    assert frame["hold"].max() == 9 and np.mean((frame["static"] == 1) == still) > 0.95
    out = tmp_path / "tool.json"
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        assert main(["payload", str(table), "--urdf", str(ur5), "--ft-joint", "ee_fixed_joint", "--base",
                     "base_link", "--group-by", "hold", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "samples moving (from the joints)" in printed and "in 10 group(s)" in printed
    doc = json.loads(out.read_text())
    assert abs(doc["mass"] - mass) < 4 * doc["stderr"]["mass"]
    assert np.all(np.abs(np.array(doc["com"]) - com) < 4 * np.array(doc["stderr"]["com"]))
    np.testing.assert_allclose(np.r_[doc["force_bias"], doc["torque_bias"]], bias,
                               atol=4 * max(np.max(doc["stderr"]["force_bias"]), np.max(doc["stderr"]["torque_bias"])))


@pytest.mark.slow
def test_bag_joints_with_the_urdf_keep_the_joints_and_the_fit_says_one_tool_is_not_enough(ur5_bag, tmp_path,
                                                                                          capsys):
    """With the URDF and the tool as a known payload the bag also gives the expected wrench; one rigid tool
    spans 3 of the 6 wrench directions, which the fit (grouped by hold) says."""
    path, q, still, ur5 = ur5_bag
    mass, com = UR5_TOOL["mass"], UR5_TOOL["com"]
    model_table = tmp_path / "ur5-model.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["dataset", str(path), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                     "--urdf", str(ur5), "--ft-joint", "ee_fixed_joint", "--sensor", "ee_fixed_joint",
                     "--base", "base_link", "--payload", f"ee_link:{mass}@{com[0]},{com[1]},{com[2]}",
                     "--no-filter", "--no-cache", "--workers", "1", "-o", str(model_table)]) == 0
        capsys.readouterr()
        assert main(["fit", str(model_table), "--inputs", "u1,u2,u3,u4,u5,u6", "--group-by", "hold",
                     "-o", str(tmp_path / "m.json")]) == 0
    frame = pd.read_csv(model_table)
    np.testing.assert_allclose(frame[UR5_JOINTS].to_numpy(), q, atol=1e-9)
    captured = capsys.readouterr()
    assert "excitation: reference wrenches span 3 of 6 directions" in captured.out
    assert "warning: reference wrenches span 3 of 6 directions" in captured.err


def test_holds_are_numbered_across_bags(tmp_path):
    """Two bags, each one still pose (/tf_static): hold 0 in the first, hold 1 in the second."""
    paths = []
    for j in range(2):
        bag = Bag("mcap")
        for i in range(60):
            bag.wrench("/ft", T0 + i * 10**7, np.r_[np.ones(6)] + 0.01 * np.sin(i + np.arange(6)), frame="ft")
        bag.tf(T0, [("base", "ft", Rotation.from_rotvec([0.0, 0.3 * j, 0.0]).as_quat(), T0)], static=True)
        paths.append(str(bag.write(tmp_path / f"pose{j}")))
    out = tmp_path / "two.csv"
    assert main(["dataset", *paths, "--wrench-topic", "/ft", "--tf", "base", "--no-filter", "-o", str(out)]) == 0
    frame = pd.read_csv(out)
    assert frame.groupby("segment")["hold"].agg(["min", "max"]).values.tolist() == [[0, 0], [1, 1]]
    assert frame["static"].eq(1).all()


def test_hold_averages_and_the_longest_hold_per_label():
    """Means, standard errors and rotations of hand-made holds; one hold per label keeps the longest."""
    hold = np.array([-1, 0, 0, 0, -1, 1, 1, -1, 2, 2, 2, 2])
    holds = Holds(hold >= 0, hold, "test")
    starts, stops = holds.ranges()
    np.testing.assert_array_equal(starts, [1, 5, 8])
    np.testing.assert_array_equal(stops, [4, 7, 12])
    wrench = np.zeros((12, 6))
    wrench[1:4, 0] = [1.0, 2.0, 6.0]  # mean 3, population std √(14/3)
    gravity = np.tile([0.0, 0.0, -9.81], (12, 1))
    turn = Rotation.from_euler("z", [[10.0], [20.0], [30.0]], degrees=True).as_matrix()
    rotation = np.repeat(np.eye(3)[None], 12, axis=0)
    rotation[1:4] = turn
    avg = hold_averages(holds, wrench, gravity, rotation)
    assert avg.n_holds == 3
    assert avg.wrench[0, 0] == pytest.approx(3.0) and avg.noise[0, 0] == pytest.approx(np.sqrt(14 / 3) / np.sqrt(3))
    np.testing.assert_allclose(avg.gravity, [[0.0, 0.0, -9.81]] * 3)
    # the rotation nearest the mean of rotations by 10°, 20°, 30° about z is the one by 20°
    np.testing.assert_allclose(avg.rotation[0], turn[1], atol=1e-12)
    np.testing.assert_array_equal(avg.start, [1, 5, 8])
    np.testing.assert_array_equal(avg.stop, [4, 7, 12])
    # labels: rows 0-7 one pose (holds 0 and 1: the longer, 0, is kept), rows 8-11 another
    labels = np.array(["a"] * 8 + ["b"] * 4, dtype=object)
    one = holds.longest_per_segment(labels)
    np.testing.assert_array_equal(one.hold, [-1, 0, 0, 0, -1, -1, -1, -1, 1, 1, 1, 1])


def test_check_reads_holds_over_the_time_column_or_the_declared_rate(tmp_path, capsys):
    """``ftcal check`` finds its holds with ftcal.data.holds: over the time column when the table has one,
    else at --rate; the same recording, told a rate 20 times too low, sees the slow moves as holds."""
    t, k, blend, still = hold_and_move(6, 1.0, 1.5, 100.0)
    poses = rotations(6, 7)
    q = slerped(poses, k, blend)
    gravity = q.inv().apply([0.0, 0.0, -9.81])
    rng = np.random.default_rng(3)
    wrench = np.c_[1.5 * gravity, np.cross([0.0, 0.0, 0.05], 1.5 * gravity)] + 0.01 * rng.normal(size=(t.size, 6))
    frame = pd.DataFrame(np.c_[q.as_quat(), wrench], columns=["qx", "qy", "qz", "qw", *WRENCH])
    plain = tmp_path / "plain.csv"
    frame.to_csv(plain, index=False)
    timed = tmp_path / "timed.csv"
    frame.assign(time=t).to_csv(timed, index=False)
    for path, extra in ((timed, []), (plain, []), (plain, ["--rate", "100"])):
        assert main(["check", str(path), "--orientation", "qx,qy,qz,qw", *extra]) == 0
        assert capsys.readouterr().out.startswith("6 static holds;")
    source = OrientationSource(("qx", "qy", "qz", "qw"))
    timed_holds = read_holds([timed], source)
    np.testing.assert_array_equal(timed_holds.start, read_holds([plain], source, rate=100.0).start)
    # each hold starts where the schedule's does (the first, at row 0) or within the slowest instants of the move
    first_rows = np.flatnonzero(np.diff(np.r_[-1, k]))
    assert np.all((timed_holds.start - first_rows <= 0) & (timed_holds.start - first_rows >= -10))
    # told 5 Hz, rows look 0.2 s apart: the moves look 20 times slower and their slow ends pass as still
    slow = read_holds([plain], source, rate=5.0)
    assert np.sum(slow.stop - slow.start) > np.sum(timed_holds.stop - timed_holds.start) + 6 * 10
    with pytest.raises(FtcalError, match="no time column 'stamp'"):
        read_holds([plain], source, time="stamp")
