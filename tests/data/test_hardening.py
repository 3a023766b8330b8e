"""One regression test per class of hostile or broken input (issue 17).

Each test names the class it guards and says why it fails on the code before
the fix. Hostile strings come from model/payload files (not trusted); the
command line is trusted.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.files.c_code import generate_c
from ftcal.files.model_files import save_model

CC = shutil.which("cc")
CXX = shutil.which("c++")
NM = shutil.which("nm")
needs_cc = pytest.mark.skipif(CC is None or NM is None, reason="needs a C compiler `cc` and `nm`")

# Names an attacker could put in a model file, each trying to end the comment or the string
# literal it lands in and declare a symbol of its own (injected_*): plain `*/`, a trailing
# backslash that splices the next line into the comment, the trigraph ??/ (a backslash under
# -std=c99), a bidirectional override, a quote and a raw newline.
HOSTILE = (
    "a */ int injected_a; /*",
    "b*\\\n/ int injected_b; /*",
    "c*??/\n/ int injected_c; /*",
    "d\u202e */ int injected_d; /* \u2066",
    'e"; int injected_e; static const char *x = "',
    "f\n#define predict injected_f\n",
    "g\\",
    "h??/",
    "i\x00\x1b[2J\U0001F600\udcff",
)


def hostile_model(n_inputs=3, n_outputs=2, **fit) -> CalibrationModel:
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (60, n_inputs))
    y = u[:, :n_outputs] * 2.0 + 0.5
    data = Dataset.from_arrays(u, y, input_names=HOSTILE[:n_inputs], output_names=HOSTILE[n_inputs:n_inputs + n_outputs])
    return CalibrationModel(1, **fit).fit(data)


def exported_symbols(obj: Path) -> set[str]:
    """The global symbols an object file defines (nm's upper-case types)."""
    out = subprocess.run([NM, "--defined-only", "-P", str(obj)], capture_output=True, text=True, check=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip() and line.split()[1].isupper()}


def defined_symbols(obj: Path) -> set[str]:
    out = subprocess.run([NM, "--defined-only", "-P", str(obj)], capture_output=True, text=True, check=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip()}


@needs_cc
def test_names_from_the_model_file_never_become_c_code(tmp_path):
    """Class: data as code in generated C (comment terminators, line splices, trigraphs, bidi, quotes).

    Before the fix the header comment only replaced ``*/``: the names ending in a
    backslash or ``??/`` spliced the next comment line (``/``) onto ``*``, which
    closed the comment and declared ``injected_b`` / ``injected_c``.
    """
    model = hostile_model()
    code = generate_c(model, name="cal", source_name="evil */ int injected_g; /*\\",
                      input_units=["N*/ int injected_h; /*", "\\", "??/"], output_units=["*\\", "/"])
    (tmp_path / "cal.h").write_text(code.header)
    (tmp_path / "cal.c").write_text(code.source)
    for text in (code.header, code.source):
        assert all(" " <= ch <= "~" or ch == "\n" for ch in text), "only printable ASCII and newlines"
        assert not re.search(r"\\\n", text) and "??" not in re.sub(r'"[^"\n]*"', "", text)
    subprocess.run([CC, "-std=c99", "-trigraphs", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c", "cal.c",
                    "-o", "cal.o"], cwd=tmp_path, check=True, capture_output=True, text=True)
    # The API is all that is exported; the file-local tables and helpers are the generator's own (cal_*):
    # nothing a name from the model file could declare.
    assert exported_symbols(tmp_path / "cal.o") == {"cal_in_range", "cal_input_names", "cal_output_names",
                                                    "cal_predict", "cal_predict_batch"}
    assert all(name.startswith("cal_") and "injected" not in name for name in defined_symbols(tmp_path / "cal.o"))
    # The string tables hold the names' exact UTF-8 bytes (lone surrogates as surrogate-escaped bytes).
    driver = ('#include <stdio.h>\n#include "cal.h"\nint main(void) { int i; for (i = 0; i < CAL_N_INPUTS; ++i) '
              'fwrite(cal_input_names[i], 1, __builtin_strlen(cal_input_names[i]) + 1, stdout); return 0; }\n')
    (tmp_path / "d.c").write_text(driver)
    subprocess.run([CC, "d.c", "cal.o", "-o", "d"], cwd=tmp_path, check=True, capture_output=True)
    out = subprocess.run([str(tmp_path / "d")], capture_output=True, check=True).stdout
    assert out.split(b"\0")[:-1] == [n.encode("utf-8", "surrogatepass") for n in HOSTILE[:3]]
    if CXX:  # the header is also C++ (extern "C")
        (tmp_path / "x.cpp").write_text('#include "cal.h"\nint main() { return CAL_N_INPUTS - 3; }\n')
        subprocess.run([CXX, "-std=c++98", "-trigraphs", "-Wall", "-Werror", "-c", "x.cpp"], cwd=tmp_path,
                       check=True, capture_output=True)


def test_names_from_the_model_file_never_become_xml_or_yaml(tmp_path):
    """Class: data as markup in generated XML (WBD comment) and YAML (ROS frame names).

    Before the fix the WBD comment copied the names verbatim, so ``-->`` closed it and
    the next text became an XML element.
    """
    import xml.etree.ElementTree as ET

    import yaml

    from ftcal.files.ros_yaml import ros_yaml_text
    from ftcal.files.wbd import format_wbd
    from ftcal.payload.parameters import PayloadParameters

    rng = np.random.default_rng(1)
    names = ["x --><group name='injected'/><!--"] + [f"u{i}" for i in range(5)]
    u = rng.uniform(-1, 1, (80, 6))
    model = CalibrationModel(1).fit(Dataset.from_arrays(u, u @ rng.normal(size=(6, 6)), input_names=tuple(names), output_names=
                                            ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz-")))
    root = ET.fromstring("<root>" + format_wbd(model, "ft") + "</root>")
    assert [g.get("name") for g in root] == ["FT_SECONDARY_CALIBRATION", "FT_OFFSET"]
    frame = 'f"\n\u2028injected: 1\x85\\'
    payload = PayloadParameters(1.0, np.zeros(3), np.zeros(3), np.zeros(3), 9.81, frame=frame)
    document = yaml.safe_load(ros_yaml_text(payload))
    assert document["gripper_com_frame_id"] == frame and "injected" not in document


def test_multi_file_export_is_all_or_nothing(tmp_path):
    """Class: lost/partial output of a multi-file export (``.h`` + ``.c``).

    The second file cannot be written (a directory stands at ``cal.c``); before the
    fix ``cal.h`` had already been renamed into place and stayed behind.
    """
    model = hostile_model()
    source = tmp_path / "m.json"
    save_model(model, source)
    out = tmp_path / "out"
    (out / "cal.c").mkdir(parents=True)
    assert main(["convert", str(source), "--to", "c", "--name", "cal", "-o", f"{out}/"]) == 2
    assert sorted(p.name for p in out.iterdir()) == ["cal.c"]
    assert (out / "cal.c").is_dir()


# ---------------------------------------------------------------- 2. never hang


def _demo_table(path: Path, n=40, extra=()) -> Path:
    """A small table with u1..u6 (and the ``extra`` input columns) and Fx..Tz."""
    rng = np.random.default_rng(2)
    names = [f"u{i}" for i in range(1, 7)] + list(extra) + ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
    values = rng.uniform(-1, 1, (n, len(names)))
    path.write_text(",".join(names) + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in values)
                    + "\n")
    return path


def _call_with_timeout(function, fifos=(), seconds=20.0):
    """Run ``function`` in a thread; if it blocks (on a FIFO), unblock it and fail."""
    import threading

    outcome = {}

    def run():
        try:
            outcome["value"] = function()
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            outcome["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        for fifo in fifos:  # a writer that opens and closes: the blocked reader sees end of file
            try:
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:
                pass
        thread.join(5)
        pytest.fail(f"{function} blocked for {seconds} s on a FIFO or device")
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")


def test_pipes_devices_and_link_loops_are_refused_by_every_reader(tmp_path):
    """Class: a FIFO, character device or symbolic-link loop given where a file is expected.

    One shared check (ftcal.runtime.inputs.check_input_file) runs in every reader; before it,
    the readers opened a FIFO and blocked until a writer came (forever), and read /dev/zero
    without end.
    """
    from ftcal.data.logs import read_recording
    from ftcal.data.tables import read_arrow
    from ftcal.files.model_files import load_model_file
    from ftcal.files.paper_xml import read_paper_xml
    from ftcal.files.targets import input_kind
    from ftcal.robot import RobotModel, load_case_config
    from ftcal.runtime.errors import FtcalError

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    loop = tmp_path / "loop.json"
    os.symlink(tmp_path / "loop2.json", loop)
    os.symlink(loop, tmp_path / "loop2.json")
    readers = {"table": read_arrow, "model": load_model_file, "paper XML": read_paper_xml, "convert": input_kind,
               "URDF": lambda p: RobotModel.load(urdf=p), "load cases": load_case_config,
               "recording": read_recording}
    for what, reader in readers.items():
        for bad, kind in ((fifo, "FIFO"), (Path("/dev/zero"), "character device"), (loop, "loop of symbolic")):
            with pytest.raises(FtcalError, match=kind) as info:
                _call_with_timeout(lambda: reader(bad), fifos=[fifo])
            assert str(bad) in str(info.value) and "\n" not in str(info.value), what


def test_pipes_and_devices_are_refused_by_the_command_line_in_one_line(tmp_path, capfd):
    """Class: the same through the CLI, for every command's file arguments (checked before any work).

    Before the fix ``ftcal fit pipe.csv`` blocked forever in the header reader.
    """
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    train = _demo_table(tmp_path / "t.csv")
    for argv in (["fit", str(fifo), "-o", str(tmp_path / "m.json")], ["info", "/dev/urandom"],
                 ["fit", str(train), str(fifo), "-o", str(tmp_path / "m.json")],
                 ["convert", "/dev/zero", "--to", "c", "-o", f"{tmp_path}/"]):
        assert _call_with_timeout(lambda: main(argv), fifos=[fifo]) == 2
        err = capfd.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "not a regular file" in err, err
    assert not (tmp_path / "m.json").exists()


def test_tf_frame_with_two_parents_and_tf_loops_are_refused():
    """Class: cycles and ambiguous parents in tf trees.

    Before the fix ``chain`` walked a breadth-first search over both parents and
    silently used whichever it met first.
    """
    from ftcal.data.tf_chain import TransformTree
    from ftcal.runtime.errors import FtcalError

    q = (0.0, 0.0, 0.0, 1.0)
    tf = TransformTree("Bag x.bag")
    tf.add("world", "base", 0.0, q, True)
    tf.add("base", "ft", 0.0, q, True)
    tf.add("table", "ft", 0.0, q, True)
    with pytest.raises(FtcalError, match="'ft' has two parents, 'base' and 'table'"):
        tf.chain("world", "ft")
    tf = TransformTree("Bag x.bag")
    for parent, child in (("a", "b"), ("b", "c"), ("c", "a")):
        tf.add(parent, child, 0.0, q, True)
    with pytest.raises(FtcalError, match="loop"):
        tf.chain("a", "c")


LOOP_URDF = """<robot name="r">
  <link name="a"/><link name="b"/><link name="c"/>
  <joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
  <joint name="j2" type="fixed"><parent link="b"/><child link="c"/></joint>
  <joint name="j3" type="fixed"><parent link="c"/><child link="b"/></joint>
</robot>"""


def _urdf_with(mass="1.0", inertia=("0.1", "0", "0", "0.1", "0", "0.1")):
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    attrs = " ".join(f'{k}="{v}"' for k, v in zip(keys, inertia))
    return (f'<robot name="r"><link name="base"/><link name="tool"><inertial><origin xyz="0 0 0"/>'
            f'<mass value="{mass}"/><inertia {attrs}/></inertial></link>'
            '<joint name="j" type="revolute"><parent link="base"/><child link="tool"/><axis xyz="0 0 1"/>'
            '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')


def test_urdf_loops_and_impossible_physics_are_refused_naming_the_link():
    """Class: URDF kinematic loops and invalid inertial data.

    Before the fix a link with two parent joints loaded without a word (one parent kept),
    and so did NaN and negative masses (every expected wrench NaN or of the wrong sign).
    """
    import warnings

    from ftcal.robot import RobotModel
    from ftcal.runtime.errors import FtcalError, FtcalWarning

    with pytest.raises(FtcalError, match="'b' is the child of two joints, 'j1' and 'j3'"):
        RobotModel.from_text(LOOP_URDF, "loop.urdf")
    for mass, message in (("nan", "mass value='nan'"), ("-2", "negative mass"), ("inf", "mass value='inf'"),
                          ("heavy", "mass value='heavy'")):
        with pytest.raises(FtcalError, match=f"link 'tool' has (a )?{message}"):
            RobotModel.from_text(_urdf_with(mass=mass), "m.urdf")
    # Principal moments 1, 0.1, 0.1: 1 > 0.1 + 0.1 breaks the triangle inequality of a real body.
    with pytest.warns(FtcalWarning, match="'tool'.*triangle"):
        RobotModel.from_text(_urdf_with(inertia=("1", "0", "0", "0.1", "0", "0.1")), "t.urdf")
    # Off-diagonal 0.2 with diagonal 0.1: eigenvalues 0.3 and -0.1, not positive semi-definite.
    with pytest.warns(FtcalWarning, match="'tool'.*not positive semi-definite"):
        RobotModel.from_text(_urdf_with(inertia=("0.1", "0.2", "0", "0.1", "0", "0.1")), "p.urdf")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        RobotModel.from_text(_urdf_with(), "ok.urdf")  # a plausible body: no warning


def test_absurd_declared_sizes_are_refused_before_allocating(tmp_path):
    """Class: well-formed files declaring absurd sizes (a million CSV columns, 10^12 samples in a .mat).

    The HDF5 .mat below is a few kB but declares 10^12 x 6 values; before the fix the reader
    asked for 48 TB (MemoryError, a traceback). The CSV header holds a million columns;
    before the fix every column was parsed and typed (seconds and gigabytes) before
    anything was refused.
    """
    import h5py

    from ftcal.core.limits import MAX_DECLARED_ELEMENTS, MAX_TABLE_COLUMNS
    from ftcal.data.logs import read_recording
    from ftcal.data.tables import table_columns
    from ftcal.runtime.errors import FtcalError

    mat = tmp_path / "huge.mat"
    with h5py.File(mat, "w") as fh:
        fh.create_group("robot_logger_device/FTs/ft").create_dataset(
            "data", shape=(6, 10**12), dtype="f8", chunks=(6, 1024))  # nothing written: fill values
    with pytest.raises(FtcalError, match=f"declares 6,000,000,000,000 values.*limit of {MAX_DECLARED_ELEMENTS:,}"):
        read_recording(mat)
    wide = tmp_path / "wide.csv"
    n = MAX_TABLE_COLUMNS + 1
    wide.write_text(",".join(f"c{i}" for i in range(n)) + "\n" + ",".join("1" for _ in range(n)) + "\n")
    with pytest.raises(FtcalError, match=f"declares {n:,} columns"):
        table_columns(wide)
    assert main(["fit", str(wide), "-o", str(tmp_path / "m.json")]) == 2


def test_csv_headers_in_other_encodings_are_refused_naming_the_encoding(tmp_path, capfd):
    """Class: text encodings of CSV headers.

    Before the fix a Latin-1 header escaped as a UnicodeDecodeError traceback, and a UTF-16
    file was reported as a CSV parse error ("Expected 2 columns, got 1") without the encoding.
    """
    for name, data, found in (("utf16.csv", "u1,u2\n1,2\n".encode("utf-16"), "UTF-16"),
                              ("latin.csv", "u1,Température\n1,2\n".encode("latin-1"), "Latin-1")):
        (tmp_path / name).write_bytes(data)
        assert main(["fit", str(tmp_path / name), "-o", str(tmp_path / "m.json")]) == 2
        err = capfd.readouterr().err
        assert len(err.strip().splitlines()) == 1 and found in err and name in err, err


def test_garbage_scheduler_addresses_and_answers_are_one_line(tmp_path, capfd):
    """Class: a --scheduler that is garbage, or a server that answers garbage.

    Before the fix a malformed address escaped as Dask's ValueError traceback, and a server
    answering with random bytes made Dask ask for exabytes (a MemoryError traceback).
    """
    import socket
    import threading

    from ftcal.runtime.errors import FtcalError
    from ftcal.runtime.executors import open_executor

    pytest.importorskip("distributed")
    train = _demo_table(tmp_path / "t.csv")
    for address in ("tcp://[::1", "nonsense://host:1"):
        assert main(["fit", str(train), "--scheduler", address, "-o", str(tmp_path / "m.json")]) == 2
        err = capfd.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "--scheduler" in err and "Traceback" not in err, err

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    stop = threading.Event()

    def answer_garbage():
        server.settimeout(0.2)
        connections = []
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            connections.append(conn)
            conn.sendall(b"\xff" * 64)  # a frame header claiming an absurd length
        for conn in connections:
            conn.close()

    thread = threading.Thread(target=answer_garbage, daemon=True)
    thread.start()
    try:
        with pytest.raises(FtcalError, match="^scheduler tcp://127.0.0.1"):
            with open_executor(f"tcp://127.0.0.1:{server.getsockname()[1]}", connect_timeout=3):
                pass
    finally:
        stop.set()
        thread.join(2)
        server.close()


# ---------------------------------------------------------------- 3. never crash the interpreter


def test_fits_too_large_for_memory_are_refused_before_allocating(tmp_path, capfd):
    """Class: a model size the CLI accepts but memory cannot hold (ARX na = nb = 50 at degree 5).

    Counted by hand: 7 inputs at degree 5 give C(12, 5) = 792 monomials, 791 without the
    constant, so one output has 6·50 + 1 + 51·791 = 40,642 columns and a Gram matrix of
    8·40,642² bytes = 13.2 GB. Before the fix numpy asked for it after reading the data
    (a MemoryError traceback under a memory limit, swapping without one); in this test the
    under-determined warning, an error under pytest, came first.
    """
    train = _demo_table(tmp_path / "t.csv", n=200, extra=("T",))
    assert main(["fit", str(train), "--degree", "5", "--na", "50", "--nb", "50", "-o", str(tmp_path / "m.json")]) == 2
    err = [line for line in capfd.readouterr().err.strip().splitlines() if not line.startswith("read ")]
    assert len(err) == 1 and "40,642 coefficients per output" in err[0] and "13.2 GB" in err[0], err
    assert "lower --degree, --na or --nb" in err[0]
    assert not (tmp_path / "m.json").exists()


def test_values_near_the_float_limit_are_refused_naming_the_column_or_option(tmp_path, capfd):
    """Class: overflow from values near 1e308, in data or in options such as ``--g``.

    Both made the payload fit's regressor overflow; before the fix numpy's LinAlgError
    ("Eigenvalues did not converge") ended the command with a traceback after three
    RuntimeWarning lines. Now the option parser and the table reader refuse them, naming
    the option or the column and line.
    """
    rng = np.random.default_rng(3)
    n = 300
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    names = ["u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"]
    data = np.column_stack([rng.normal(size=(n, 6)), q])
    table = tmp_path / "poses.csv"
    table.write_text(",".join(names) + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in data))
    out = str(tmp_path / "p.json")
    with pytest.raises(SystemExit) as info:
        main(["payload", str(table), "--orientation", "qx,qy,qz,qw", "--g", "1e308", "-o", out])
    err = capfd.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(err) == 1 and "--g: must be at most 1e+12" in err[0], err
    data[41, 2] = 1e300
    table.write_text(",".join(names) + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in data))
    assert main(["payload", str(table), "--orientation", "qx,qy,qz,qw", "-o", out]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "column 'u3' holds 1e+300 at line 43" in err[0], err
    assert not (tmp_path / "p.json").exists()


# ---------------------------------------------------------------- 5. what users see


def test_errors_quoting_file_text_stay_one_line_and_cannot_drive_the_terminal(tmp_path, capfd):
    """Class: error and warning lines that quote text from files (column names, frames).

    A column name holding a newline and an ANSI escape (clear screen) is quoted by the
    missing-column message; before the fix it printed raw: two lines, and the escape
    reached the terminal.
    """
    table = tmp_path / "t.csv"
    table.write_text('"a\nb\x1b[2J\u202e",u2\n1,2\n')
    assert main(["fit", str(table), "-o", str(tmp_path / "m.json")]) == 2
    err = capfd.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "\x1b" not in err and "\u202e" not in err, repr(err)
    assert "\\x1b[2J" in err and "\\u202e" in err


# ---------------------------------------------------------------- 4. never compute from corrupt input


@pytest.mark.parametrize("kind", ["db3-file", "mcap-file", "ros1"])
def test_truncated_bags_are_refused_naming_the_bag(tmp_path, capfd, kind):
    """Class: truncated or corrupted bags (sqlite .db3, .mcap, ROS 1 .bag).

    Before the fix a .db3 cut short escaped as apsw.CorruptError ("database disk image is
    malformed") with a traceback, from the message loop that open_bag did not guard (the
    .mcap and .bag cases passed already; they guard the same reader).
    """
    import sys

    from bag_data import Bag

    rng = np.random.default_rng(4)
    bag = Bag(kind)
    for i in range(400):
        bag.wrench("/ft", 10**9 + i * 10**7, rng.normal(size=6))
    written = bag.write(tmp_path / "run")
    whole = written.read_bytes()
    for fraction in (0.35, 0.5, 0.65, 0.8, 0.95):
        cut = tmp_path / f"cut{int(fraction * 100)}{written.suffix}"
        cut.write_bytes(whole[:int(len(whole) * fraction)])
        code = main(["dataset", str(cut), "--wrench-topic", "/ft", "-o", str(tmp_path / "d.parquet")])
        err = [line for line in capfd.readouterr().err.strip().splitlines() if line]
        assert code in (0, 2) and "Traceback" not in "\n".join(err), err
        if code == 2:
            assert len(err) == 1 and cut.name in err[0], err
            assert not (tmp_path / "d.parquet").exists()


def test_unknown_xml_encodings_and_nameless_urdf_elements_are_one_line(tmp_path):
    """Class: XML that parses into what the readers did not expect.

    Before the fix ``<?xml version="1.0" encoding="uuf-8"?>`` escaped as a LookupError
    traceback (paper XML, URDF), and a URDF joint without a name as a TypeError from the
    hint listing fixed joints.
    """
    from ftcal.files.paper_xml import read_paper_xml
    from ftcal.robot import RobotModel
    from ftcal.runtime.errors import FtcalError

    xml = tmp_path / "m.xml"
    xml.write_text('<?xml version="1.0" encoding="uuf-8"?><group name="modelClassParams"/>')
    with pytest.raises(FtcalError, match="encoding"):
        read_paper_xml(xml)
    with pytest.raises(FtcalError, match="encoding"):
        RobotModel.from_text('<?xml version="1.0" encoding="uuf-8"?><robot name="r"/>', "r.urdf")
    with pytest.raises(FtcalError, match="a <joint> element has no name"):
        RobotModel.from_text('<robot name="r"><link name="a"/><link name="b"/><joint type="fixed">'
                             '<parent link="a"/><child link="b"/></joint></robot>', "r.urdf")


def test_command_output_quoting_file_text_cannot_drive_the_terminal(tmp_path, capsys):
    """Class: stdout lines quoting names from files (``ftcal info`` lists a model's inputs).

    Before the fix an input named with an ANSI escape (clear screen) and a right-to-left
    override reached the terminal raw.
    """
    rng = np.random.default_rng(6)
    u = rng.uniform(-1, 1, (50, 2))
    model = CalibrationModel(1).fit(Dataset.from_arrays(u, u * 3.0, input_names=("a\x1b[2J", "b\u202e"),
                                                        output_names=("y1", "y2")))
    save_model(model, tmp_path / "m.json")
    assert main(["info", str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\u202e" not in out
    assert "a\\x1b[2J" in out and "b\\u202e" in out
