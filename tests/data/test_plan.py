"""ftcal plan: candidates within limits, greedy D-optimal design, --from, execution order, bad input.

References are independent of the code under test: forward kinematics of the demo arm
written out with scipy rotations, monomials from scikit-learn's PolynomialFeatures, the
static payload regressor written with numpy cross products, brute-force greedy selection
with numpy's slogdet, and the optimal path of collinear points.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation
from sklearn.preprocessing import PolynomialFeatures

from ftcal.cli import main
from ftcal.plan import PlanRequest, design_experiment
from ftcal.plan.design import greedy_design, greedy_design_factored
from ftcal.plan.information import payload_blocks, payload_rows
from ftcal.plan.order import short_path
from ftcal.robot import RobotModel, parse_payload_spec
from ftcal.sim.plan_arm import ARM_URDF

FTCAL = str(Path(sys.executable).with_name("ftcal"))
LIMITS = {"shoulder_pitch": (-2.0, 2.0), "elbow_pitch": (-2.5, 2.5), "wrist_roll": (-3.1, 3.1),
          "wrist_pitch": (-2.0, 2.0)}
HEAVY = "tool:3@0,0.05,0.08"
MASSLESS_URDF = """<?xml version="1.0"?>
<robot name="bare">
  <link name="base"><inertial><mass value="5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="upper"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="tool"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="ft_joint" type="fixed"><parent link="upper"/><child link="tool"/><origin xyz="0 0 0.2"/></joint>
</robot>
"""


@pytest.fixture
def ftcal(monkeypatch, capsys):
    """Run the command line in this process (from the test's folder): returns (exit code, stdout, stderr)."""
    def run(*args: str, cwd: Path) -> tuple[int, str, str]:
        monkeypatch.chdir(cwd)
        code = main(list(args))
        out, err = capsys.readouterr()
        return code, out, err
    return run


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    return RobotModel.from_text(ARM_URDF, "arm.urdf")


@pytest.fixture
def arm_urdf(tmp_path) -> Path:
    path = tmp_path / "arm.urdf"
    path.write_text(ARM_URDF)
    return path


def sensor_height(q: np.ndarray) -> np.ndarray:
    """Height of the demo arm's sensor origin, from its URDF by hand: pitch about y, roll about z."""
    def ry(a):
        return Rotation.from_euler("y", a)

    heights = []
    for q1, q2, q3, q4 in q:
        elbow = ry(q1).apply([0, 0, 0.35])
        forearm = ry(q1) * ry(q2)
        wrist = forearm.apply([0, 0, 0.3])
        roll = forearm * Rotation.from_euler("z", q3)
        pitch_joint = roll.apply([0, 0, 0.03])
        sensor = (roll * ry(q4)).apply([0, 0, 0.04])
        heights.append(0.4 + elbow[2] + wrist[2] + pitch_joint[2] + sensor[2])
    return np.array(heights)


def test_planned_poses_respect_limits_pins_and_height(arm):
    request = PlanRequest((None, parse_payload_spec(HEAVY)), 25, degree=2, ranges={"elbow_pitch": (-1.0, 0.5)},
                          fixed={"wrist_roll": 0.3}, min_height=0.9, n_candidates=2000, seed=3)
    plan = design_experiment(arm, request)
    q, load, reference, _ = plan.table()
    assert set(plan.space.free) == {"shoulder_pitch", "elbow_pitch", "wrist_pitch"}
    for j, name in enumerate(arm.joint_names):
        low, high = (-1.0, 0.5) if name == "elbow_pitch" else LIMITS[name]
        if name == "wrist_roll":
            assert np.all(q[:, j] == 0.3)
        else:
            assert np.all((q[:, j] >= low) & (q[:, j] <= high)), name
    assert np.all(sensor_height(q) >= 0.9 - 1e-12)
    # the candidates were drawn over the whole box: the height limit is what removed the low ones
    assert np.all(sensor_height(plan.candidates.q[:200]) >= 0.9 - 1e-12)
    assert reference.sum() > 0 and set(load) <= {0, 1}


def _restricted_log_det(features: np.ndarray, basis: np.ndarray) -> float:
    """log det of the information of ``features`` (n, p) restricted to the columns of ``basis`` (p, k)."""
    sign, value = np.linalg.slogdet(basis.T @ features.T @ features @ basis)
    return value if sign > 0 else -np.inf  # a design that leaves an excitable direction unexcited


@pytest.mark.parametrize("degree", [1, 2])
def test_planned_calibration_information_beats_100_random_designs(arm, degree):
    loads = (None, parse_payload_spec("tool:1@0.03,0,0.04"), parse_payload_spec(HEAVY))
    plan = design_experiment(arm, PlanRequest(loads, 30, degree=degree, n_candidates=1500, seed=1))
    w = plan.candidates.wrench.reshape(-1, 6)  # candidate (configuration, load) pairs, configuration-major
    # Monomials by scikit-learn on forces in N and torques in N·dm (any affine rescaling spans the same
    # polynomials; the rescaling only keeps the numbers near one)
    poly = PolynomialFeatures(degree)
    scale = np.array([1, 1, 1, 10, 10, 10.0])
    features = poly.fit_transform(w * scale / 10.0)
    # The wrench lies on a manifold (|F| is fixed per load, T ⊥ F): restrict to the directions the candidates excite.
    eig, vec = np.linalg.eigh(features.T @ features)
    basis = vec[:, eig > 1e-9 * eig.max()]
    n_loads = plan.candidates.n_loads
    planned = _restricted_log_det(features[plan.configuration * n_loads + plan.load], basis)
    rng = np.random.default_rng(7)
    randoms = [_restricted_log_det(features[rng.choice(len(w), 30, replace=False)], basis) for _ in range(100)]
    assert np.isfinite(planned) and planned > max(randoms)
    assert sum(np.isfinite(randoms)) >= 50  # most random designs are a real comparison


def _payload_regressor_by_hand(gravity: np.ndarray, load: np.ndarray, n_loads: int) -> np.ndarray:
    """F = m g + f_b, T = (m c) × g + t_b; columns: 6 biases, then m, m·c of each load."""
    rows = np.zeros((len(gravity), 6, 6 + 4 * n_loads))
    for i, (g, k) in enumerate(zip(gravity, load)):
        rows[i, :, :6] = np.eye(6)
        rows[i, :3, 6 + 4 * k] = g
        for a in range(3):
            rows[i, 3:, 6 + 4 * k + 1 + a] = np.cross(np.eye(3)[a], g)
    return rows


def test_planned_payload_information_beats_100_random_designs(arm):
    loads = (None, parse_payload_spec(HEAVY))
    plan = design_experiment(arm, PlanRequest(loads, 14, objective="payload", n_candidates=1500, noise=(1.0, 1.0)))
    g = plan.candidates.gravity
    n = plan.candidates.n_configurations

    def log_det(config, load):
        rows = _payload_regressor_by_hand(g[config], load, 2).reshape(-1, 14)
        return np.linalg.slogdet(rows.T @ rows)[1]

    planned = log_det(plan.configuration, plan.load)
    rng = np.random.default_rng(11)
    randoms = []
    for _ in range(100):
        pick = rng.choice(2 * n, 14, replace=False)
        randoms.append(log_det(pick // 2, pick % 2))
    assert planned > max(randoms)


def test_greedy_updates_match_brute_force_greedy():
    rng = np.random.default_rng(0)
    for r, p in ((1, 5), (3, 4)):
        rows = rng.standard_normal((60, r, p))
        start = 0.1 * np.eye(p)
        chosen = greedy_design(rows, 8, start)
        information = start.copy()
        taken: list[int] = []
        for _ in range(8):
            gains = [-np.inf if c in taken else np.linalg.slogdet(information + rows[c].T @ rows[c])[1]
                     for c in range(60)]
            best = int(np.argmax(gains))
            taken.append(best)
            information += rows[best].T @ rows[best]
        assert chosen.tolist() == taken


def test_factored_payload_greedy_matches_the_generic_one():
    rng = np.random.default_rng(1)
    gravity = rng.standard_normal((300, 3))
    load = rng.integers(0, 3, 300)
    rows = payload_rows(gravity, load, 3, (0.2, 0.02))
    # payload_rows against the regressor by hand, weights aside
    assert np.allclose(rows * np.repeat([0.2, 0.02], 3)[None, :, None], _payload_regressor_by_hand(gravity, load, 3))
    start = 1e-3 * np.eye(rows.shape[-1])
    features = np.column_stack([np.ones(300), gravity])
    assert greedy_design_factored(features, load, payload_blocks(3, (0.2, 0.02)), 12, start).tolist() == \
        greedy_design(rows, 12, start).tolist()


def test_short_path_of_collinear_points_is_sorted():
    rng = np.random.default_rng(2)
    x = rng.permutation(np.linspace(0.0, 5.0, 25))
    points = np.column_stack([x, 2 * x])
    path = short_path(points, np.array([-1.0, -2.0]))
    assert np.all(np.diff(x[path]) > 0)


def run_plan(ftcal, cwd: Path, urdf: Path, out: str, *extra: str) -> pd.DataFrame:
    code, stdout, stderr = ftcal("plan", "--urdf", str(urdf), "--candidates", "2000", "-o", out, *extra, cwd=cwd)
    assert code == 0, stderr
    assert "no collision checking" in stdout
    return pd.read_csv(cwd / out)


def test_order_mounts_each_load_once_and_returns_to_the_reference(ftcal, tmp_path, arm_urdf):
    table = run_plan(ftcal, tmp_path, arm_urdf, "plan.csv", "--load", "none", "--load", "tool:1@0,0,0.05", "--load", HEAVY,
                     "--poses", "40", "--reference-every", "7")
    assert list(table.columns) == [*LIMITS, "load", "reference", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
    assert (table["reference"] == 0).sum() == 40
    runs = (table["load"] != table["load"].shift()).sum()
    assert runs == table["load"].nunique()
    joints = table[list(LIMITS)].to_numpy()
    references = joints[table["reference"] == 1]
    assert np.all(references == references[0])  # one reference pose
    for _, group in table.groupby("load", sort=False):
        flags = group["reference"].to_numpy()
        assert flags[0] == 1 and flags[-1] == 1
        at = np.flatnonzero(flags)
        assert np.all(np.diff(at) - 1 <= 7)
    # the expected wrench of the reference rows differs only by the load: F = m g with g at the reference
    heavy_ref = table[(table["reference"] == 1) & (table["load"] == 2)][["Fx", "Fy", "Fz"]].to_numpy()[0]
    none_ref = table[(table["reference"] == 1) & (table["load"] == 0)][["Fx", "Fy", "Fz"]].to_numpy()[0]
    assert np.linalg.norm(heavy_ref) / np.linalg.norm(none_ref) == pytest.approx((0.6 + 3.0) / 0.6)


@pytest.mark.slow
def test_html_page_has_the_coverage_figure_and_the_safety_note(ftcal, tmp_path, arm_urdf):
    loads = ["--load", "none", "--load", HEAVY]
    run_plan(ftcal, tmp_path, arm_urdf, "first.csv", *loads, "--poses", "12")
    run_plan(ftcal, tmp_path, arm_urdf, "plan.csv", *loads, "--poses", "12", "--from", "first.csv", "--html", "plan.html")
    page = (tmp_path / "plan.html").read_text()
    assert "data:image/png;base64," in page and "no collision checking" in page


def test_from_adds_poses_where_the_recorded_data_is_thin(ftcal, tmp_path, arm_urdf):
    # Recorded: only the bare hand, with the wrist in a narrow region.
    narrow = ["--joint-range", "shoulder_pitch:0:0.3", "--joint-range", "elbow_pitch:0:0.3",
              "--joint-range", "wrist_roll:0:0.3", "--joint-range", "wrist_pitch:0:0.3"]
    run_plan(ftcal, tmp_path, arm_urdf, "old.csv", "--load", "none", "--poses", "30", "--degree", "1", *narrow)
    common = ["--load", "none", "--load", HEAVY, "--poses", "12", "--degree", "1", "--seed", "5"]
    fresh = run_plan(ftcal, tmp_path, arm_urdf, "fresh.csv", *common)
    added = run_plan(ftcal, tmp_path, arm_urdf, "added.csv", *common, "--from", "old.csv")
    old = pd.read_csv(tmp_path / "old.csv")
    wrench = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]

    def information(frame):
        x = np.column_stack([np.ones(len(frame)), frame[wrench].to_numpy()])
        return x.T @ x

    recorded = information(old)
    eig, vec = np.linalg.eigh(recorded)
    thin = vec[:, :3]  # the three directions the recorded data excites least
    gain = {name: np.trace(thin.T @ information(t[t["reference"] == 0]) @ thin)
            for name, t in (("fresh", fresh), ("added", added))}
    assert gain["added"] > gain["fresh"]
    # and the recorded load gets fewer new poses than without the recording
    assert (added[added["reference"] == 0]["load"] == 0).sum() < (fresh[fresh["reference"] == 0]["load"] == 0).sum()


@pytest.mark.parametrize("args, message", [
    (["--fixed", "knee=0"], "--fixed knee: no movable joint"),
    (["--joint-range", "knee:0:1"], "--joint-range knee: no movable joint"),
    (["--joint-range", "elbow_pitch:1:0.5"], "empty range"),
    (["--joint-range", "elbow_pitch:3:4"], "empty within the URDF limits"),
    (["--fixed", "elbow_pitch=9"], "outside the joint's URDF limits"),
    (["--candidates", "5", "--poses", "50"], "--poses 50: only 5 candidate poses"),
    (["--min-height", "5"], "--poses 10: only 0 candidate poses"),
    (["--load", "tool:abc"], "Payload spec 'tool:abc'"),
    (["--degree", "11"], "--degree 11"),
    (["--from", "missing.csv"], "missing.csv"),
])
def test_bad_input_is_one_line_and_exit_2(ftcal, tmp_path, arm_urdf, args, message):
    base = ["plan", "--urdf", str(arm_urdf), "--candidates", "300", "-o", "out.csv"]
    if "--poses" not in args:
        base += ["--poses", "10"]
    code, _, stderr = ftcal(*base, *args, cwd=tmp_path)
    assert code == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], stderr
    assert not (tmp_path / "out.csv").exists()


def test_loads_that_make_nothing_identifiable(ftcal, tmp_path):
    urdf = tmp_path / "bare.urdf"
    urdf.write_text(MASSLESS_URDF)
    base = ["plan", "--urdf", str(urdf), "--ft-joint", "ft_joint", "--poses", "5", "--candidates", "200", "-o", "o.csv"]
    code, _, stderr = ftcal(*base, "--load", "none", cwd=tmp_path)
    assert code == 2 and stderr.count("\n") == 1
    assert "nothing is identifiable" in stderr
    # A vertical joint axis never tilts the sensor: gravity in sensor axes is constant, so the wrench is
    # too (nothing for a calibration) and the mass is not separable from the force bias (payload).
    urdf.write_text(MASSLESS_URDF.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 0 1"/>'))
    code, _, stderr = ftcal(*base, "--load", "tool:1@0,0,0.1", cwd=tmp_path)
    assert code == 2 and stderr.count("\n") == 1 and "nothing is identifiable" in stderr
    code, _, stderr = ftcal(*base, "--load", "tool:1@0,0,0.1", "--objective", "payload", cwd=tmp_path)
    assert code == 2 and stderr.count("\n") == 1
    assert "m[0]" in stderr and "Fz_bias" in stderr
    assert not (tmp_path / "o.csv").exists()


BRANCHED_URDF = """<?xml version="1.0"?>
<robot name="branched">
  <link name="base"><inertial><mass value="5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="upper"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="forearm"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="hand"><inertial><origin xyz="0.2 0 0"/><mass value="2"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="other"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="roll" type="revolute"><parent link="upper"/><child link="forearm_ft_parent"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="forearm_ft_parent"/>
  <joint name="ft_joint" type="fixed"><parent link="forearm_ft_parent"/><child link="forearm"/><origin xyz="0 0 0.2"/></joint>
  <joint name="wrist" type="revolute"><parent link="forearm"/><child link="hand"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="side" type="revolute"><parent link="base"/><child link="other"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""


def test_only_the_chain_to_the_sensor_moves(ftcal, tmp_path):
    urdf = tmp_path / "branched.urdf"
    urdf.write_text(BRANCHED_URDF)
    base = ["plan", "--urdf", str(urdf), "--ft-joint", "ft_joint", "--poses", "6", "--candidates", "300"]
    code, _, stderr = ftcal(*base, "-o", "a.csv", cwd=tmp_path)
    assert code == 0, stderr
    free = pd.read_csv(tmp_path / "a.csv")
    assert [c for c in free.columns if c not in ("load", "reference", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz")] == \
        ["shoulder", "roll"]
    code, _, stderr = ftcal(*base, "--joint-range", "wrist:0:0.5", "-o", "b.csv", cwd=tmp_path)
    assert code == 2 and "--joint-range wrist: the joint is not on the chain" in stderr
    # a joint beyond the sensor can be pinned: it moves the hand's mass in the sensor frame
    code, _, stderr = ftcal(*base, "--fixed", "wrist=0.5", "-o", "c.csv", cwd=tmp_path)
    assert code == 0, stderr
    pinned = pd.read_csv(tmp_path / "c.csv")
    assert np.all(pinned["wrist"] == 0.5)
    # beyond the sensor: the forearm (1 kg) and the hand (2 kg), whatever the pose: |F| = 3 kg · g
    force = np.linalg.norm(pinned[["Fx", "Fy", "Fz"]].to_numpy(), axis=1)
    assert force == pytest.approx(np.full(len(force), 3.0 * 9.81))


@pytest.mark.slow
def test_demo_scenario_plan_beats_random(tmp_path):
    done = subprocess.run([FTCAL, "demo", "--scenario", "plan", "--quick", "--out", "d"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    summary = json.loads((tmp_path / "d" / "summary.json").read_text())
    assert summary["calibration_ratio_mean"] < 1.0
    assert "planned/random" in done.stdout
    assert (tmp_path / "d" / "arm.urdf").exists() and (tmp_path / "d" / "plan.csv").exists()
