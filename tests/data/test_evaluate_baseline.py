"""`ftcal evaluate --baseline --tare`: ratios to the vendor's matrix (or another model) after the re-tare users do.

The held-out recordings are simulated with known truth: a tool at rest in a few orientations (1.5 s holds,
1 s moves), the reference wrench its weight, raw channels the vendor's wrench with a known gain/cross-talk
error G, a per-recording offset the training data never had, and white noise of known size. Every
expected number is computed here from G, the offsets and the noise, not read from ftcal.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ftcal
from ftcal.core.baseline import compare_to_baseline
from ftcal.data.tare import tare_offsets

FTCAL = str(Path(sys.executable).with_name("ftcal"))
OUT = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
RAW = ["u1", "u2", "u3", "u4", "u5", "u6"]
RATE, HOLD_S, MOVE_S = 100.0, 1.5, 1.0
SIGMA = 0.05  # N and N·m, white noise of every channel
COM = np.array([0.01, -0.02, 0.08])


def gain_error(seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 0.04 * rng.standard_normal((6, 6))


def recording(rng, mass: float, n_poses: int = 6):
    """(time, reference wrench, first hold's rows): holds at random orientations joined by slerp-like moves."""
    dirs = rng.standard_normal((n_poses, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    g, t = [], []
    n_hold, n_move = int(HOLD_S * RATE), int(MOVE_S * RATE)
    for k in range(n_poses):
        g.append(np.repeat(dirs[k][None], n_hold, axis=0))
        if k + 1 < n_poses:
            s = np.linspace(0, 1, n_move + 2)[1:-1, None]
            m = (1 - s) * dirs[k] + s * dirs[k + 1]
            g.append(m / np.linalg.norm(m, axis=1, keepdims=True))
    g = np.vstack(g)
    force = mass * 9.81 * g
    wrench = np.column_stack([force, np.cross(COM, force)])
    return np.arange(len(g)) / RATE, wrench, (0, n_hold)


def held_out(seed: int = 1, offsets=None):
    """Three load groups x two recordings each; returns (frame, first-hold rows per recording, offsets)."""
    rng = np.random.default_rng(seed)
    G = gain_error()
    rows, firsts = [], []
    offsets = offsets if offsets is not None else rng.normal(0.0, 2.0, (6, 6))
    start = 0
    for r in range(6):
        mass = (1.0, 2.0, 4.0)[r // 2]
        t, y, (a, b) = recording(rng, mass)
        u = y @ (np.eye(6) + G).T + offsets[r] + rng.normal(0.0, SIGMA, y.shape)
        frame = pd.DataFrame(np.column_stack([u, y]), columns=RAW + OUT)
        frame.insert(0, "time", t)
        frame["segment"] = r
        frame["load"] = f"m{mass:g}"
        rows.append(frame)
        firsts.append((start + a, start + b))
        start += len(frame)
    return pd.concat(rows, ignore_index=True), firsts, offsets


def training_model():
    """An affine model fitted on the same sensor without offsets: it undoes G exactly (up to noise)."""
    rng = np.random.default_rng(11)
    G = gain_error()
    y = rng.normal(0.0, 20.0, (4000, 6))
    u = y @ (np.eye(6) + G).T + rng.normal(0.0, SIGMA, y.shape)
    frame = pd.DataFrame(np.column_stack([u, y]), columns=RAW + OUT)
    return ftcal.fit(frame, inputs=RAW, outputs=OUT).model


def test_tare_at_the_first_hold_removes_each_recordings_offset():
    frame, firsts, offsets = held_out()
    model = training_model()
    untared = ftcal.evaluate(model, frame, baseline="identity", tare="none").comparison
    tared = ftcal.evaluate(model, frame, baseline="identity", tare="first-hold").comparison
    y, u = frame[OUT].to_numpy(), frame[RAW].to_numpy()
    G = gain_error()
    # By hand: the model's untared error is the offset seen through (I + G)^-1; after the re-tare only noise
    # (and the noise of the hold's mean) is left.
    inverse = np.linalg.inv(np.eye(6) + G)
    expected_untared = np.sqrt(np.mean(np.repeat(offsets @ inverse.T, frame.groupby("segment").size(), axis=0) ** 2,
                                       axis=0))
    model_untared = np.array([r.model_rmse for r in untared.rows[:6]])
    np.testing.assert_allclose(model_untared, expected_untared, rtol=0.05)
    noise = np.array([r.model_rmse for r in tared.rows[:6]])
    assert np.all(noise < 1.6 * SIGMA) and np.all(noise > 0.7 * SIGMA)
    # The vendor's matrix tared at the same (hand-known) first holds: G (y - y at the first hold) plus noise.
    errors = []
    for (a, b), (_, part) in zip(firsts, frame.groupby("segment")):
        e = part[RAW].to_numpy() - part[OUT].to_numpy()
        errors.append(e - e[a - part.index[0]:b - part.index[0]].mean(axis=0))
    hand = np.sqrt(np.mean(np.vstack(errors) ** 2, axis=0))
    baseline = np.array([r.baseline_rmse for r in tared.rows[:6]])
    np.testing.assert_allclose(baseline, hand, rtol=0.03)
    # ratios as printed: model / baseline per axis, and the model wins on every fold by far
    assert all(r.verdict == "better" for r in tared.rows)
    assert tared.rows[0].ratio == pytest.approx(noise[0] / baseline[0])
    del u, y


def test_per_file_tares_once_so_a_second_recording_keeps_its_offset_change():
    frame, firsts, offsets = held_out()
    error = (frame[RAW].to_numpy() - frame[OUT].to_numpy())
    recordings, files = frame["segment"].to_numpy(), np.zeros(len(frame), dtype=int)
    y, t = frame[OUT].to_numpy(), frame["time"].to_numpy()
    first = tare_offsets([error], y, recordings, files, "first-hold", time=t)[0]
    once = tare_offsets([error], y, recordings, files, "per-file", time=t)[0]
    second = recordings == 1
    # Once per file: recording 1 carries the offset of recording 0's first hold; each its own with first-hold.
    np.testing.assert_allclose(once[second].mean(axis=0), first[recordings == 0].mean(axis=0), atol=1e-12)
    # by hand: each first hold reads its offset plus G times the hold's reference (noise averages out)
    G, y_first = gain_error(), [frame[OUT].to_numpy()[a:b].mean(axis=0) for a, b in firsts[:2]]
    change = offsets[1] + G @ y_first[1] - offsets[0] - G @ y_first[0]
    np.testing.assert_allclose(first[second][0] - once[second][0], change, atol=0.03)


def test_verdict_ties_when_the_folds_disagree_and_is_better_when_every_fold_wins():
    rng = np.random.default_rng(3)
    base = rng.standard_normal((600, 6))
    folds = np.repeat(["a", "b", "c"], 200)
    # wins 2x on fold a, loses 2x on fold b, equal on c: the fold log ratios are log 2, -log 2, 0
    scale = np.repeat([0.5, 2.0, 1.0], 200)[:, None]
    mixed = compare_to_baseline(scale * base, base, folds, ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"], "b")
    assert {r.verdict for r in mixed.rows} == {"ties"}
    by_hand = np.sqrt(np.sum((scale[:, 0] * base[:, 0]) ** 2) / np.sum(base[:, 0] ** 2))
    assert mixed.rows[0].ratio == pytest.approx(by_hand, rel=1e-12)
    np.testing.assert_allclose(mixed.rows[0].as_dict()["fold_ratios"], [0.5, 2.0, 1.0], rtol=1e-12)
    same = compare_to_baseline(base, base, folds, OUT, "itself")
    assert {r.verdict for r in same.rows} == {"ties"}
    worse = compare_to_baseline(1.5 * base, base, folds, OUT, "b")
    assert {r.verdict for r in worse.rows} == {"worse"}


def run(*args, cwd):
    return subprocess.run([FTCAL, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_cli_prints_ratio_and_verdict_and_refuses_bad_input_in_one_line(tmp_path):
    frame, _, _ = held_out()
    frame.to_parquet(tmp_path / "held.parquet")
    ftcal.save_model(training_model(), tmp_path / "model.json")
    done = run("evaluate", "model.json", "held.parquet", "--baseline", "identity", "--tare", "first-hold",
               cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "against baseline identity" in done.stdout and "both tared (first-hold)" in done.stdout
    assert "3 fold(s) = the groups (m1, m2, m4)" in done.stdout
    fx = next(line for line in done.stdout.splitlines() if line.startswith("Fx ") and "better" in line)
    name, model_rmse, base_rmse, ratio, _, margin, _, noise, _, unit = fx.split()  # fold ratios: "min-max"
    # the model is 7x better on every fold: log ratio about log 7 = 1.9, far beyond its spread
    assert float(margin) > 1.5 and float(noise) < float(margin)
    assert float(ratio) == pytest.approx(float(model_rmse) / float(base_rmse), rel=2e-3) and unit == "N"
    shown = json.loads(run("evaluate", "model.json", "held.parquet", "--baseline", "model.json", "--json",
                           cwd=tmp_path).stdout)["baseline"]
    assert {r["verdict"] for r in shown["rows"]} == {"ties"}  # a model against itself
    for args, words in ((["--tare", "first"], "--tare"), (["--baseline", "missing.json"], "missing.json")):
        bad = run("evaluate", "model.json", "held.parquet", *args, cwd=tmp_path)
        assert bad.returncode == 2 and words in bad.stderr and "Traceback" not in bad.stderr
        assert len(bad.stderr.strip().splitlines()) == 1


def test_report_page_carries_the_same_baseline_rows_as_evaluate(tmp_path):
    import re

    frame, _, _ = held_out()
    frame.to_parquet(tmp_path / "held.parquet")
    ftcal.save_model(training_model(), tmp_path / "model.json")
    done = run("report", "model.json", "held.parquet", "--baseline", "identity", "--tare", "first-hold", "-o",
               "page.html", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    page = (tmp_path / "page.html").read_text(encoding="utf-8")
    assert "Against the baseline" in page
    cells = re.findall(r"<td[^>]*>([^<]*)</td>", page[page.index("Against baseline"):])
    fx = cells.index("Fx")
    expected = ftcal.evaluate(tmp_path / "model.json", frame, baseline="identity", tare="first-hold").comparison
    assert float(cells[fx + 3]) == pytest.approx(expected.rows[0].ratio, rel=2e-3) and cells[fx + 5] == "better"
