"""``DatasetResult`` renders its description from the table and the recordings read (issue #43)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ftcal.insitu.bags import BagTable
from ftcal.workflow.datasets import DatasetResult


def test_the_description_follows_the_table_and_the_recordings():
    n = 7
    table = BagTable({"time": np.arange(float(n)), "u1": np.zeros(n), "u2": np.ones(n)}, ())
    result = DatasetResult(table, "bags", 2, ["a note"])
    assert result.summary().split("\n") == ["a note", f"{n} samples from 2 bag(s), columns time,u1,u2"]
    other = replace(result, table=BagTable({"time": np.arange(3.0)}, ()), n_recordings=5)
    assert other.description == "3 samples from 5 bag(s), columns time"
    assert result.to_dict()["n_recordings"] == 2 and result.to_dict()["n_holds"] == 0
