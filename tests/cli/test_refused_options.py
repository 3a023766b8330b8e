"""Options a mode does not use are refused in one line (exit 2), never silently ignored (issue 39):
the MLP and the degree search's options, ``check --history``, ``check --dynamic``, the robot-model and motion
options beside a column gravity source (payload, ``--rebias``, check, compensate), and wrench columns that the
gravity source reads too."""

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main


@pytest.fixture(scope="module")
def holds(tmp_path_factory):
    """Eight static holds of a 1.2 kg tool (bias and centre of mass known) and its payload file."""
    root = tmp_path_factory.mktemp("holds")
    rng = np.random.default_rng(0)
    q = np.repeat(Rotation.random(8, random_state=1).as_quat(), 50, axis=0)
    g = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])
    force = 1.2 * g + [1.0, -2.0, 0.5]
    wrench = np.c_[force, np.cross([0.01, 0.02, 0.05], 1.2 * g) + [0.1, 0.0, -0.1]]
    frame = pd.DataFrame(np.c_[wrench + rng.normal(scale=0.01, size=wrench.shape), q],
                         columns=["u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"])
    frame["time"] = np.arange(len(frame)) * 0.01
    frame.to_csv(root / "poses.csv", index=False)
    assert main(["payload", str(root / "poses.csv"), "--orientation", "qx,qy,qz,qw", "-o", str(root / "p.json")]) == 0
    return root


def refused(argv, capsys, *words):
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], (code, err)
    for word in words:
        assert word in err[0], err[0]
    return err[0]


@pytest.mark.parametrize("extra, named", [
    (["--angular-velocity", "a,b,c"], "--angular-velocity"),
    (["--linear-acceleration", "a,b,c"], "--linear-acceleration"),
    (["--angular-acceleration", "a,b,c"], "--angular-acceleration"),
    (["--sensor", "s"], "--sensor"),
    (["--ft-frame", "x"], "--ft-frame"),
    (["--base", "b"], "--base"),
    (["--degrees"], "--degrees"),
    (["--inputs", "u1,u2,u3,qx,qy,qz"], "'qx', 'qy', 'qz'"),
])
@pytest.mark.parametrize("mode", ["payload", "rebias", "check", "compensate"])
def test_options_of_another_source_are_refused_naming_them(holds, capsys, mode, extra, named):
    data, pose = str(holds / "poses.csv"), ["--orientation", "qx,qy,qz,qw"]
    out = str(holds / f"{mode}-out.json")
    argv = {"payload": ["payload", data, *pose, "-o", out],
            "rebias": ["payload", data, *pose, "--rebias", str(holds / "p.json"), "-o", out],
            "check": ["check", data, *pose],
            "compensate": ["compensate", str(holds / "p.json"), data, *pose, "-o", out.replace(".json", ".csv")]}[mode]
    refused(argv + extra, capsys, named)
    assert not (holds / f"{mode}-out.json").exists() and not (holds / f"{mode}-out.csv").exists()
    # the same command without the option runs: the refusal is the option's, not the data's
    assert main(argv) in (0, 1)
    for name in (f"{mode}-out.json", f"{mode}-out.csv"):
        (holds / name).unlink(missing_ok=True)


def test_the_same_source_through_the_library_refuses_both_column_sources(holds):
    from ftcal.runtime.errors import FtcalError
    from ftcal.workflow.payload import identify_payload

    with pytest.raises(FtcalError, match="not both"):
        identify_payload(str(holds / "poses.csv"), orientation=("qx", "qy", "qz", "qw"),
                         gravity_columns=("qx", "qy", "qz"))


def test_check_refuses_dynamic_and_history_refuses_the_other_modes_options(holds, capsys, tmp_path):
    refused(["check", str(holds / "poses.csv"), "--orientation", "qx,qy,qz,qw", "--dynamic"], capsys, "--dynamic")
    line = refused(["check", "--history", "SN1", "--history-dir", str(tmp_path), "--html", str(tmp_path / "h.html"),
                    "--rate", "5"], capsys, "--html", "--rate")
    assert "--history-dir" in line and not (tmp_path / "h.html").exists()


@pytest.fixture(scope="module")
def mlp_table(tmp_path_factory):
    root = tmp_path_factory.mktemp("mlp")
    rng = np.random.default_rng(2)
    u = rng.normal(size=(200, 3))
    frame = pd.DataFrame(np.c_[u, np.tanh(u)], columns=["u1", "u2", "u3", "Fx", "Fy", "Fz"])
    frame["g"] = np.repeat(["a", "b"], 100)
    frame.loc[5, "u1"] = np.nan
    frame.to_csv(root / "d.csv", index=False)
    return root / "d.csv"


MLP = ["--inputs", "u1,u2,u3", "--outputs", "Fx,Fy,Fz", "--family", "mlp", "--hidden", "3", "--max-iter", "20",
       "--group-by", "g"]


@pytest.mark.parametrize("extra", [["--max-degree", "3"], ["--lambdas", "1,2"], ["--penalties", "ridge"],
                                   ["--select-per", "output"], ["--budget", "5"], ["--verbose"]])
def test_the_mlp_refuses_the_degree_search_options(mlp_table, capsys, tmp_path, extra):
    refused(["fit", str(mlp_table), *MLP, "--drop-incomplete", *extra, "-o", str(tmp_path / "m.json")], capsys,
            extra[0])
    assert not (tmp_path / "m.json").exists()


def test_the_mlp_honours_drop_incomplete(mlp_table, capsys, tmp_path):
    refused(["fit", str(mlp_table), *MLP, "-o", str(tmp_path / "m.json")], capsys, "'u1'", "--drop-incomplete")
    assert main(["fit", str(mlp_table), *MLP, "--drop-incomplete", "-o", str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr()
    assert "read 199 samples" in out.out + out.err and "dropped 1 row(s)" in out.out + out.err
