"""A joint that appears halfway through a bag (a gripper) loses no sample of the others (issue 28)."""

import sys
import warnings
from pathlib import Path

import numpy as np

from ftcal.data.bags import BagTopics, read_bag

from bag_data import Bag  # noqa: E402

T0, MS = 10**9, 10**6


def bag_with_a_late_gripper(tmp_path, kind="mcap"):
    bag = Bag(kind)
    for k in range(200):
        t = T0 + k * 10 * MS
        bag.wrench("/ft", t, np.full(6, float(k)))
        if k < 100:
            bag.joints("/joint_states", t, ("a",), [0.01 * k])
        else:
            bag.joints("/joint_states", t, ("gripper", "a"), [0.5, 0.01 * k])
    return bag.write(tmp_path / "run")


def test_every_joint_message_is_kept_and_the_late_joint_is_absent_before_it_appears(tmp_path):
    rec = read_bag(bag_with_a_late_gripper(tmp_path), BagTopics("/ft", joints="/joint_states"))
    k = np.arange(200)
    a = rec.joints.data[:, rec.joints.columns.index("a")]
    gripper = rec.joints.data[:, rec.joints.columns.index("gripper")]
    np.testing.assert_allclose(a, 0.01 * k, atol=1e-12)  # all 200 messages, on one clock
    assert np.all(np.isnan(gripper[:100])) and np.all(gripper[100:] == 0.5)


def test_dataset_keeps_every_sample_and_drops_only_the_late_joint(tmp_path, capsys):
    import pandas as pd

    from ftcal.cli import main

    path = bag_with_a_late_gripper(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["dataset", str(path), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                     "-o", str(tmp_path / "d.parquet")]) == 0
    assert "gripper" in capsys.readouterr().err  # said, with the joint's name
    table = pd.read_parquet(tmp_path / "d.parquet")
    assert len(table) >= 199 and "a" in table.columns and "gripper" not in table.columns
