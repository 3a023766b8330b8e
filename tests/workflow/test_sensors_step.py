"""``ftcal sensors`` is a step (``robot_sensors``) whose result holds the robot and renders the table (#43).

Physical invariant: a 2 kg payload on the right hand adds 2 kg to the mass beyond the right arm's sensor
and nothing beyond the left arm's; the table renders the masses the result holds.
"""

from __future__ import annotations

import pytest

from ftcal.cli import main
from ftcal.workflow.datasets import robot_sensors


def _mass(result, name):
    return next(s["mass_beyond"] for s in result.sensors if s["name"] == name)


def test_a_payload_adds_its_mass_beyond_the_sensors_it_is_beyond(capsys):
    bare = robot_sensors(robot="iCubGenova04")
    loaded = robot_sensors(robot="iCubGenova04", payload=("r_hand:2@0.1,0,0",))
    assert _mass(loaded, "r_arm_ft") == pytest.approx(_mass(bare, "r_arm_ft") + 2.0, abs=1e-9)
    assert _mass(loaded, "l_arm_ft") == pytest.approx(_mass(bare, "l_arm_ft"), abs=1e-9)
    row = next(line for line in loaded.lines() if line.lstrip().startswith("r_arm_ft "))
    assert row.rstrip().endswith(f"{_mass(bare, 'r_arm_ft') + 2.0:.4f}")
    assert "payloads: 2 kg on r_hand" in loaded.summary() and "payloads:" not in bare.summary()
    assert main(["sensors", "--model", "iCubGenova04", "--payload", "r_hand:2@0.1,0,0"]) == 0
    assert capsys.readouterr().out == loaded.summary() + "\n"  # the command prints the step's text
    assert loaded.to_dict()["total_mass"] == pytest.approx(bare.to_dict()["total_mass"] + 2.0, abs=1e-9)
