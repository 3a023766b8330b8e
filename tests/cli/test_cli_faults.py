"""Faults and hostile input across every command: nothing lost, nothing non-finite, one line, exit 2.

Each class of problem is tried on every command where it can happen: an output that is one of
the inputs (same name, another spelling, a symbolic link, a hard link); signals in the middle of
a write or of the parallel expected-wrench step (real processes, real signals); values that
overflow; hostile model files, tables, HDF5 files, names and payload files.
"""

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import cli_data as cd
import h5py
import numpy as np
import pandas as pd
import pytest
from test_insitu import make_recording
from test_logs_mat import write_v73
from test_robot_model import TINY_URDF

from ftcal.cli import main
from ftcal.files.model_json import digest
from ftcal.runtime.atomic import protected_inputs, write_text_atomic
from ftcal.runtime.errors import FtcalError, FtcalWarning

FTCAL = str(Path(sys.executable).with_name("ftcal"))


# ------------------------------------------------------------------ helpers
def run(argv) -> int:
    """``main`` in-process; the CLI prints its own warnings as `warning: ...` lines on stderr."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        return main([str(a) for a in argv])


def fails(capfd, argv, fragment):
    """Exit code 2, exactly one stderr line `ftcal <cmd>: error: ...` holding ``fragment``, no traceback."""
    code = run(argv)
    err = capfd.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ftcal {argv[0]}: error: "), err
    assert fragment in lines[0], lines[0]
    return lines[0]


def usage_fails(capfd, argv, fragment):
    """argparse refuses the value: exit 2 and the reason on stderr."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in argv])
    assert exc.value.code == 2
    err = capfd.readouterr().err
    assert fragment in err and "Traceback" not in err, err


def leftovers(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.tmp"))


class Files:
    """One small instance of every kind of input file."""

    def __init__(self, folder: Path):
        rng = np.random.default_rng(5)
        self.dir = folder
        self.train = folder / "train.csv"
        self.val = folder / "val.csv"
        cd.training_frame(rng, 400).to_csv(self.train, index=False)
        cd.validation_frame(rng, 100, 0).to_csv(self.val, index=False)
        self.model = folder / "m2.json"
        assert run(["fit", str(self.train), "--degree", "2", "-o", str(self.model)]) == 0
        self.urdf = folder / "tiny.urdf"
        self.urdf.write_text(TINY_URDF)
        self.joints = folder / "joints.csv"
        pd.DataFrame({"shoulder": np.linspace(-1, 1, 5)}).to_csv(self.joints, index=False)
        self.log = folder / "rec.mat"
        make_recording(self.log, write_v73)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return Files(tmp_path_factory.mktemp("faults"))


# ------------------------------------------------------------------ an output is never an input
COMMANDS = {
    # command: (argv with OUT standing for the output, the input the output aliases, output suffix)
    "fit": (lambda f, out: ["fit", f.train, "-o", out], "train", ".json"),
    "predict": (lambda f, out: ["predict", f.model, f.val, "-o", out], "val", ".csv"),
    "convert": (lambda f, out: ["convert", f.model, "--to", "json", "-o", out], "model", ".json"),
    "expected": (lambda f, out: ["expected", "--urdf", f.urdf, "--joints", f.joints, "--no-cache", "-o", out],
                 "joints", ".csv"),
    "dataset": (lambda f, out: ["dataset", f.log, "--urdf", f.urdf, "--sensor", "arm_ft", "--no-cache",
                                "-o", out], "log", ".parquet"),
    "report": (lambda f, out: ["report", f.model, f.val, "-o", out], "val", ".html"),
}


@pytest.mark.parametrize("how", ["same name", "other spelling", "symbolic link", "hard link"])
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_an_output_that_is_an_input_is_refused(capfd, files, tmp_path, command, how):
    build, which, suffix = COMMANDS[command]
    target = Path(getattr(files, which))
    if how in ("same name", "other spelling") and target.suffix != suffix:
        pytest.skip("the output suffix check refuses this one already")
    out = {"same name": target,
           "other spelling": target.parent / "." / ".." / target.parent.name / target.name,
           "symbolic link": tmp_path / f"link{suffix}",
           "hard link": tmp_path / f"hard{suffix}"}[how]
    if how == "symbolic link":
        out.symlink_to(target)
    elif how == "hard link":
        os.link(target, out)
    before = target.read_bytes()
    fails(capfd, build(files, out), "is also an input of this command")
    assert target.read_bytes() == before
    assert not leftovers(files.dir) and not leftovers(tmp_path)


def test_the_atomic_writer_refuses_a_protected_input(tmp_path):
    source = tmp_path / "in.csv"
    source.write_text("precious\n")
    os.link(source, tmp_path / "alias.csv")
    with protected_inputs([str(source)]):
        with pytest.raises(FtcalError, match="is also an input"):
            write_text_atomic(tmp_path / "alias.csv", "overwritten\n")
    assert source.read_text() == "precious\n"
    write_text_atomic(tmp_path / "alias.csv", "now allowed\n")  # outside the command, no protection


# ------------------------------------------------------------------ signals
def wait_for(condition, timeout=120.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.005)
    return False


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_during_a_write_leaves_no_temporary_file(files, tmp_path, signum):
    big = tmp_path / "big.csv"
    u = cd.random_inputs(np.random.default_rng(0), 400_000)
    pd.DataFrame(u, columns=list(cd.INPUTS)).to_csv(big, index=False)
    out = tmp_path / "wrench.csv"
    proc = subprocess.Popen([FTCAL, "predict", str(files.model), str(big), "-o", str(out)],
                            stderr=subprocess.PIPE, text=True)
    assert wait_for(lambda: leftovers(tmp_path) or proc.poll() is not None), "no temporary file appeared"
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signum, err
    assert err.strip().splitlines()[-1] == f"ftcal predict: terminated by {signal.Signals(signum).name}"
    assert "Traceback" not in err
    assert not leftovers(tmp_path) and not out.exists()


def children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs /proc to find the worker processes")
def test_ctrl_c_during_parallel_expected_wrenches_stops_the_workers(files, tmp_path):
    joints = tmp_path / "many.csv"
    pd.DataFrame({"shoulder": np.sin(np.arange(2_000_000) * 1e-3)}).to_csv(joints, index=False)
    out = tmp_path / "w.csv"
    # A terminal's Ctrl-C goes to the whole foreground process group: workers included.
    proc = subprocess.Popen([FTCAL, "expected", "--urdf", str(files.urdf), "--joints", str(joints),
                             "--workers", "2", "--no-cache", "-o", str(out)],
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    assert wait_for(lambda: len(children(proc.pid)) >= 2 or proc.poll() is not None)
    workers = children(proc.pid)
    time.sleep(1.0)  # let the workers start computing
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)  # never hangs
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == ["ftcal expected: interrupted"], err
    assert wait_for(lambda: not any(alive(w) for w in workers), timeout=30)
    assert not out.exists() and not leftovers(tmp_path)


# ------------------------------------------------------------------ parameters refused at the boundary
def test_bad_parameters(capfd, files, tmp_path):
    robot = ["--urdf", files.urdf]
    usage_fails(capfd, ["expected", *robot, "--joints", files.joints, "--gravity", "nan", "0", "0",
                        "-o", tmp_path / "e.csv"], "must be a finite number")
    usage_fails(capfd, ["dataset", files.log, *robot, "--sensor", "arm_ft", "--gravity", "0", "inf", "0",
                        "-o", tmp_path / "d.csv"], "must be a finite number")
    usage_fails(capfd, ["dataset", files.log, *robot, "--sensor", "arm_ft", "--rate", "inf",
                        "-o", tmp_path / "d.csv"], "must be a finite number > 0")
    fails(capfd, ["dataset", files.log, *robot, "--sensor", "arm_ft", "--rate", "1e12", "--no-cache",
                  "-o", tmp_path / "d.csv"], "more than 100 times")
    usage_fails(capfd, ["demo", "--seed", "-1", "--out", tmp_path / "demo"], "must be >= 0")
    fails(capfd, ["demo", "--out", files.train], "is not a folder")
    fails(capfd, ["demo", "--out", "/dev/null"], "is not a folder")
    usage_fails(capfd, ["convert", files.model, "--to", "icub-firmware", "--serial", "../../x",
                        "-o", tmp_path], "becomes part of a file name")
    assert not list(tmp_path.iterdir())


def test_payload_file_with_wrong_types(capfd, files, tmp_path):
    for text, fragment in (('[[payload]]\nframe = "forearm"\nmass = true\n', "payload[0].mass must be a number"),
                           ('[[payload]]\nframe = "forearm"\nmass = 1.0\ncom = "up"\n', "com must be a list"),
                           ('convention = 5\n', "'convention' must be a table")):
        toml = tmp_path / "p.toml"
        toml.write_text(text)
        fails(capfd, ["dataset", files.log, "--urdf", files.urdf, "--sensor", "arm_ft", "--payload-file", toml,
                      "--no-cache", "-o", tmp_path / "d.csv"], fragment)


# ------------------------------------------------------------------ every output finite
def edited_model(source: Path, target: Path, edit) -> Path:
    """A copy of a model file changed by ``edit(doc)``, with its digest recomputed: valid but hostile."""
    doc = json.loads(source.read_text())
    edit(doc)
    doc["sha256"] = digest(doc)
    target.write_text(json.dumps(doc))
    return target


def test_overflowing_predictions_are_refused(capfd, files, tmp_path):
    # Coefficients of 1e300 on the quadratic terms: inputs of a few units overflow to inf. The
    # training ranges shrink to the offsets (where the quadratic terms vanish), or loading refuses
    # the file first (a prediction that overflows inside its own range).
    def huge(doc):
        for row, exps in zip(doc["coefficients"], doc["terms"]["exponents"]):
            if sum(exps) == 2:  # 28 terms of 1e308 sum to inf
                row[:] = [1e308] * len(row)
        for variable in doc["inputs"]:
            variable["range"] = [variable["offset"]] * 2
    model = edited_model(files.model, tmp_path / "huge.json", huge)
    out = tmp_path / "w.csv"
    fails(capfd, ["predict", model, files.val, "-o", out], "non-finite value(s)")
    assert not out.exists() and not leftovers(tmp_path)
    fails(capfd, ["evaluate", model, files.val], "predictions overflow")
    code = run(["evaluate", model, files.val, "--json"])
    captured = capfd.readouterr()
    assert code == 2 and captured.out == ""  # no partial JSON
    assert len(captured.err.strip().splitlines()) == 1


def test_raw_conversion_overflow_is_refused_in_paper_xml(capfd, files, tmp_path):
    # An input scale of 1e-200: its raw-input degree-2 coefficients are ~1e400. Its training range
    # shrinks to the offset with it, or loading refuses the file first (a prediction that overflows
    # inside its own range: tests/data/test_hardening_consistency.py).
    model = edited_model(files.model, tmp_path / "tiny-scale.json",
                         lambda doc: doc["inputs"][0].update(scale=1e-200, range=[doc["inputs"][0]["offset"]] * 2))
    out = tmp_path / "m.xml"
    fails(capfd, ["convert", model, "--to", "paper-xml", "-o", out], "overflows float64")
    assert not out.exists() and not leftovers(tmp_path)


# ------------------------------------------------------------------ hostile model files
def model_text_cases(files: Path):
    good = files.model.read_text()
    doc = json.loads(good)

    def with_digest(edit):
        d = json.loads(good)
        edit(d)
        d["sha256"] = digest(d)
        return json.dumps(d)

    deep = with_digest(lambda d: d["fit"]["metrics"].update(deep="@"))
    nested = deep.replace('"@"', "[" * 100_000 + "]" * 100_000)
    huge_int = with_digest(lambda d: d["fit"].update(n_samples=12345)).replace("12345", "9" * 5000)
    return {
        "float degree": (with_digest(lambda d: d["model"].update(degree=2.0)), "is not of type 'integer'"),
        "huge integer": (huge_int, "more than 18 digits"),
        "overflowing float": (good.replace(repr(doc["coefficients"][0][0]), "1e400", 1), "overflows float64"),
        "duplicate key": (good.replace('"format": "ftcal-model"', '"format": "ftcal-model", "format": "ftcal-model"'),
                          "appears twice"),
        "deep nesting": (nested, "nested too deeply"),
        "metrics of the wrong type": (with_digest(lambda d: d["fit"]["metrics"].update(rmse="small")),
                                      "fit.metrics.rmse"),
        "metrics of the wrong length": (with_digest(lambda d: d["fit"]["metrics"].update(rmse=[1.0, 2.0])),
                                        "fit.metrics.rmse has 2 values"),
        "bad fingerprint": (with_digest(lambda d: d["fit"].update(training_segments=[{"rows": 1}])),
                            "training_segments"),
    }


@pytest.mark.parametrize("case", ["float degree", "huge integer", "overflowing float", "duplicate key",
                                  "deep nesting", "metrics of the wrong type", "metrics of the wrong length",
                                  "bad fingerprint"])
def test_hostile_model_files(capfd, files, tmp_path, case):
    text, fragment = model_text_cases(files)[case]
    path = tmp_path / "hostile.json"
    path.write_text(text)
    for command in (["info", path], ["evaluate", path, files.val], ["predict", path, files.val, "-o", tmp_path / "p.csv"]):
        fails(capfd, command, fragment)


def test_an_absurdly_large_model_file_is_refused_before_reading(capfd, files, tmp_path):
    path = tmp_path / "big.json"
    with open(path, "wb") as fh:
        fh.write(files.model.read_bytes())
        fh.truncate(101 * 10**6)  # sparse: no 101 MB written
    fails(capfd, ["info", path], "too large for a model file")


def test_model_files_without_fingerprints_still_load(capfd, files, tmp_path):
    old = edited_model(files.model, tmp_path / "old.json", lambda doc: doc["fit"].pop("training_segments"))
    assert run(["info", str(old)]) == 0
    assert run(["evaluate", str(old), str(files.val)]) == 0
    assert "warning" not in capfd.readouterr().err


# ------------------------------------------------------------------ tables
def test_table_columns_that_are_not_numbers(capfd, files, tmp_path):
    frame = pd.read_csv(files.train)
    dup = tmp_path / "dup.csv"
    text = files.train.read_text().split("\n", 1)
    dup.write_text(text[0].replace("u2", "u1") + "\n" + text[1])  # two columns named u1
    fails(capfd, ["fit", dup, "-o", tmp_path / "m.json"], "the column name 'u1' appears 2 times")
    flags = tmp_path / "bool.csv"
    frame.assign(u3=np.arange(len(frame)) % 2 == 0).to_csv(flags, index=False)
    fails(capfd, ["fit", flags, "-o", tmp_path / "m.json"], "input column 'u3' holds bool values")
    dates = tmp_path / "dates.csv"
    frame.assign(T=pd.date_range("2024-01-01", periods=len(frame), freq="h")).to_csv(dates, index=False)
    fails(capfd, ["fit", dates, "-o", tmp_path / "m.json"], "input column 'T' holds")
    flags.with_suffix(".parquet").write_bytes(b"")
    frame.assign(u3=np.arange(len(frame)) % 2 == 0).to_parquet(flags.with_suffix(".parquet"))
    fails(capfd, ["fit", flags.with_suffix(".parquet"), "-o", tmp_path / "m.json"], "holds bool values")
    joints = tmp_path / "joints.csv"
    joints.write_text("shoulder\n0.1\nabc\n0.3\n")
    fails(capfd, ["expected", "--urdf", files.urdf, "--joints", joints, "--no-cache", "-o", tmp_path / "e.csv"],
          "'shoulder'")
    recording = tmp_path / "rec.csv"
    recording.write_text("time,arm_ft_u1,arm_ft_u2,arm_ft_u3,arm_ft_u4,arm_ft_u5,arm_ft_u6,shoulder\n"
                         "0.0,1,2,3,4,5,6,0.1\n0.01,1,2,x,4,5,6,0.2\n0.02,1,2,3,4,5,6,0.3\n")
    fails(capfd, ["dataset", recording, "--urdf", files.urdf, "--sensor", "arm_ft", "--no-temperature",
                  "--no-cache", "-o", tmp_path / "d.csv"], "column 'arm_ft_u3' line 3 holds 'x'")
    assert not list(tmp_path.glob("*.json")) and not list(tmp_path.glob("e.csv"))


# ------------------------------------------------------------------ hostile HDF5 recordings
def test_hdf5_external_links_are_never_followed(capfd, files, tmp_path):
    secret = tmp_path / "secret.h5"
    with h5py.File(secret, "w") as fh:
        fh["data"] = np.ones((300, 6))
    log = tmp_path / "linked.mat"
    make_recording(log, write_v73)
    with h5py.File(log, "a") as fh:
        fts = fh["robot_logger_device/FTs/arm_ft_sensor"]
        del fts["data"]
        fts["data"] = h5py.ExternalLink(str(secret), "/data")
    fails(capfd, ["dataset", log, "--urdf", files.urdf, "--sensor", "arm_ft", "--no-cache",
                  "-o", tmp_path / "d.csv"], "is a link to another file")


@pytest.mark.parametrize("kind", ["soft", "hard"])
def test_hdf5_link_loops_are_refused(capfd, files, tmp_path, kind):
    log = tmp_path / "loop.mat"
    make_recording(log, write_v73)
    with h5py.File(log, "a") as fh:
        group = fh["robot_logger_device/FTs"]
        group["loop"] = h5py.SoftLink("/robot_logger_device/FTs") if kind == "soft" else group
    fails(capfd, ["dataset", log, "--urdf", files.urdf, "--sensor", "arm_ft", "--no-cache", "-o", tmp_path / "d.csv"],
          "/robot_logger_device/FTs/loop links back to /robot_logger_device/FTs, which contains it (a loop")


# ------------------------------------------------------------------ names
def test_a_model_name_with_dollars_in_the_report(capfd, files, tmp_path):
    model = tmp_path / "cost$x$_{2}.json"
    model.write_bytes(files.model.read_bytes())
    out = tmp_path / "r.html"
    assert run(["report", str(model), str(files.val), "-o", str(out)]) == 0, capfd.readouterr().err
    assert "cost$x$_{2}" in out.read_text()


def test_firmware_serial_names_stay_in_the_folder(capfd, tmp_path):
    frame = cd.frame(*[np.random.default_rng(1).uniform(-1, 1, (200, 6)), None])
    y = frame[list(cd.INPUTS[:6])].to_numpy() @ np.diag([0.5, 0.4, 0.3, 0.02, 0.02, 0.01])
    data = tmp_path / "d.csv"
    frame.assign(**{n: y[:, j] for j, n in enumerate(cd.OUTPUTS)}).to_csv(data, index=False)
    assert run(["fit", str(data), "--inputs", "u1,u2,u3,u4,u5,u6", "-o", str(tmp_path / "a.json")]) == 0
    assert run(["convert", str(tmp_path / "a.json"), "--to", "icub-firmware", "--serial", "SN-1.2",
                 "-o", str(tmp_path / "fw") + "/"]) == 0
    assert [p.name for p in (tmp_path / "fw").iterdir()] == ["matrix_SN-1.2.txt"]


# ------------------------------------------------------------------ training data in the evaluation data
def test_evaluate_warns_when_the_data_holds_training_segments(capfd, files, tmp_path):
    assert run(["evaluate", str(files.model), str(files.val)]) == 0
    assert "training segment" not in capfd.readouterr().err
    # The training file inside another file, after other rows, read as one segment: still found.
    mixed = tmp_path / "mixed.csv"
    pd.concat([pd.read_csv(files.val), pd.read_csv(files.train)]).to_csv(mixed, index=False, float_format="%.17g")
    for data in (files.train, mixed):
        assert run(["evaluate", str(files.model), str(data)]) == 0
        err = capfd.readouterr().err
        assert "contains 1 of the 1 training segments" in err and "400 samples" in err, err
    assert run(["report", str(files.model), str(mixed), "-o", str(tmp_path / "r.html")]) == 0
    out, err = capfd.readouterr()
    assert "training segments" in err
    # The training rows carry a load column, the validation rows none: a default never fails a command, it
    # is left unused and the reason is said (a --group-by load the user gives is still refused).
    assert "its 'load' column has empty cells, so it is not used by default" in out, out
    assert run(["report", str(files.model), str(mixed), "--group-by", "load", "-o", str(tmp_path / "r2.html")]) == 2
    assert "group column 'load' has empty cells" in capfd.readouterr().err


# ------------------------------------------------------------------ the cache from the command line
def test_expected_uses_cache_dir_and_survives_a_damaged_entry(capfd, files, tmp_path):
    cache = tmp_path / "cache"
    first, second = tmp_path / "a.csv", tmp_path / "b.csv"
    argv = ["expected", "--urdf", str(files.urdf), "--joints", str(files.joints), "--cache-dir", str(cache)]
    assert run([*argv, "-o", str(first)]) == 0
    entries = list(cache.glob("expected-*.npz"))
    assert len(entries) == 1
    entries[0].write_bytes(entries[0].read_bytes()[:100])  # truncated
    assert run([*argv, "-o", str(second)]) == 0
    err = capfd.readouterr().err
    assert f"ignoring the expected-wrench cache entry {entries[0]}" in err
    pd.testing.assert_frame_equal(pd.read_csv(first), pd.read_csv(second))
    assert not list(files.dir.rglob("*ftcal-cache*"))
