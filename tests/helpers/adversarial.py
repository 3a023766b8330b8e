"""An adversarial pass over the ftcal command line: hostile and broken inputs of every kind.

``python tests/helpers/adversarial.py [--sample N] [--workers 2] [--out DIR]`` builds valid
input files (tables, models, payloads, URDFs, load-case TOML, .mat logs, bags),
derives hostile or broken variants of each (truncations, bit flips, garbage,
FIFOs, devices, link loops, other encodings, deep nesting, absurd sizes,
injection strings in names, NaN/1e308 numbers, cycles, impossible physics) and
runs them through the commands that read them. Each case ends in one of:

``clean``      exit 0 with its outputs, or exit 2 with exactly one ``error:`` line, no
               traceback, no output or temporary file left behind;
``hang``       no answer within the timeout;
``crash``      the process died from a signal;
``traceback``  an exception escaped, or the error was not one line;
``injection``  generated C/YAML/XML carries something the file smuggled in
               (extra symbols after compiling, extra YAML keys or XML elements);
``lost``       exit 0 without its output, or a failure that left output behind;
``verdict``    ``check`` printed PASS beside a non-finite metric;
``nonfinite``  exit 0 with NaN or inf in a CSV or JSON output;
``noise``      Python's words on the terminal (numpy reprs, RuntimeWarning).

Besides files, every option of every subcommand is read from ftcal's own parser
(:func:`parser_options`) and driven with hostile values of its kind (numbers, column
lists, structured values, choices, paths: FIFOs, folders, missing and garbage files;
names with line breaks) on a quick valid invocation of its command
(:func:`base_invocations`). An option whose kind has no generator, or a subcommand
without a base invocation, stops the run (:func:`uncovered`), unless :data:`EXEMPT`
says why.

Cases run in-process (``ftcal.cli.main``) inside worker subprocesses that the
runner restarts after a hang or a crash, so one bad case cannot stop the run.
Nothing here is imported by the test suite except :func:`run` (tests/cli/test_adversarial.py).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import random
import re
import select
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

HERE = Path(__file__).resolve().parent
TIMEOUT_S = 60.0
INJECTED = "pwned"  # every injection string tries to declare or add something with this name
HOSTILE_NAMES = (
    f"a */ int {INJECTED}_1; /*", f"b*\\\n/ int {INJECTED}_2; /*", f"c*??/\n/ int {INJECTED}_3; /*",
    f'd"; int {INJECTED}_4; //', f"e\u202e */ int {INJECTED}_5; /*", f"f\n{INJECTED}: 1\n",
    f"g --><group name='{INJECTED}'/><!--", "h\x00\x1b[2J", "i\\", "j??/", "\udcff", "k" * 5000,
)
TABLE_COLUMNS = ["u1", "u2", "u3", "u4", "u5", "u6", "T", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
URDF = """<?xml version="1.0"?>
<robot name="tiny">
  <link name="base"><inertial><origin xyz="0 0 0"/><mass value="5.0"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="upper"><inertial><origin xyz="0 0 0"/><mass value="0.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="forearm"><inertial><origin xyz="0.2 0 0"/><mass value="1.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="arm_ft_sensor" type="fixed"><parent link="upper"/><child link="forearm"/>
    <origin xyz="0 0 -0.1" rpy="0 0 0"/></joint>
  <sensor name="arm_ft" type="force_torque"><parent joint="arm_ft_sensor"/>
    <force_torque><frame>sensor</frame><measure_direction>child_to_parent</measure_direction></force_torque>
    <origin rpy="0 0 0" xyz="0 0 0"/></sensor>
</robot>
"""


# ------------------------------------------------------------------ valid fixtures


def make_fixtures(root: Path) -> dict[str, Path]:
    """Valid inputs of every kind, written with ftcal itself or the formats' own libraries."""
    import numpy as np
    import pandas as pd

    from ftcal.cli import main

    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    n = 400
    u = rng.uniform(-1, 1, (n, 6))
    frame = pd.DataFrame(np.column_stack([u * 3000 + 5000, rng.uniform(25, 40, n), u @ rng.normal(size=(6, 6))]),
                         columns=TABLE_COLUMNS)
    frame["load"] = np.repeat(["a", "b"], n // 2)
    fx = {"csv": root / "train.csv", "parquet": root / "train.parquet"}
    frame.to_csv(fx["csv"], index=False)
    frame.to_parquet(fx["parquet"], index=False)
    quiet = open(os.devnull, "w")
    old = sys.stdout, sys.stderr
    sys.stdout = sys.stderr = quiet
    try:
        assert main(["fit", str(fx["csv"]), "--degree", "2", "-o", str(root / "model.json")]) == 0
        assert main(["convert", str(root / "model.json"), "--to", "paper-xml", "-o", str(root / "model.xml")]) == 0
        adc = frame[["u1", "u2", "u3", "u4", "u5", "u6"]].copy() - 5000
        for k, c in enumerate(TABLE_COLUMNS[7:]):
            adc[c] = frame[c]
        adc.to_csv(root / "adc.csv", index=False)
        assert main(["fit", str(root / "adc.csv"), "--inputs", "u1,u2,u3,u4,u5,u6", "--degree", "1",
                     "-o", str(root / "affine.json")]) == 0
        from scipy.spatial.transform import Rotation

        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        g = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])  # gravity in the sensor frame
        force = 1.2 * g + [1.0, -2.0, 0.5]
        torque = np.cross([0.01, 0.02, 0.05], 1.2 * g) + [0.1, 0.0, -0.1]
        wrench = np.column_stack([force, torque]) + rng.normal(scale=0.01, size=(n, 6))
        poses = pd.DataFrame(np.column_stack([wrench, q]),
                             columns=["u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"])
        poses.to_csv(root / "poses.csv", index=False)
        poses.assign(time=np.arange(n) * 0.01).to_csv(root / "live.csv", index=False)  # for `ftcal live --replay`
        assert main(["payload", str(root / "poses.csv"), "--orientation", "qx,qy,qz,qw", "--frame", "ft",
                     "-o", str(root / "payload.json")]) == 0
    finally:
        sys.stdout, sys.stderr = old
        quiet.close()
    fx.update(model=root / "model.json", xml=root / "model.xml", affine=root / "affine.json",
              poses=root / "poses.csv", payload=root / "payload.json", live=root / "live.csv")
    fx["urdf"] = root / "tiny.urdf"
    fx["urdf"].write_text(URDF)
    fx["joints"] = root / "joints.csv"
    pd.DataFrame({"shoulder": np.linspace(-1, 1, 50)}).to_csv(fx["joints"], index=False)
    import pyarrow.parquet as pq

    # A Parquet file as another tool writes it: uncompressed, plain-encoded, no page checksums.
    fx["parquet-plain"] = root / "plain.parquet"
    pq.write_table(pq.read_table(fx["parquet"]), fx["parquet-plain"], compression="none", use_dictionary=False,
                   write_page_checksum=False)
    from ftcal.sim.logger_mat import RobotLog, Stream, write_robot_log

    t = np.arange(200) * 0.01
    log = RobotLog({"arm_ft": Stream(t, rng.normal(size=(200, 6)))},
                   {"arm_ft": Stream(t, 30 + 0.1 * rng.normal(size=200))}, ("shoulder",), Stream(t, np.sin(t)[:, None]))
    fx["mat-v73"] = write_robot_log(root / "rec73.mat", log, version="7.3")
    fx["mat-v5"] = write_robot_log(root / "rec5.mat", log, version="5")
    sys.path.insert(0, str(HERE))
    from bag_data import Bag

    for kind, name in (("ros1", "run"), ("mcap-file", "run"), ("db3-file", "run")):
        bag = Bag(kind)
        for i in range(60):
            bag.wrench("/ft", 10**9 + i * 10**7, rng.normal(size=6))
            bag.temperature("/temp", 10**9 + i * 10**7, 30.0)
            bag.joints("/joint_states", 10**9 + i * 10**7, ("shoulder",) if i < 30 else ("shoulder", "gripper"),
                       [0.1 * np.sin(i / 10)] + ([0.5] if i >= 30 else []))
        fx[kind] = bag.write(root / f"{kind}-{name}")
    fx.update(surface_fixtures(root, fx))
    return fx


def surface_fixtures(root: Path, fx: dict) -> dict:
    """Inputs of the surfaces added since the first pass: acceptance tests and their history, plans,
    re-tares, MLP models."""
    from ftcal.cli import main
    from ftcal.sim.plan_arm import ARM_URDF

    out = {"arm": root / "arm.urdf", "history": root / "history", "plan": root / "plan.csv",
           "mlp": root / "mlp.json"}
    out["arm"].write_text(ARM_URDF)
    quiet = open(os.devnull, "w")
    old = sys.stdout, sys.stderr
    sys.stdout = sys.stderr = quiet
    try:
        main(["check", "--accept", str(fx["model"]), str(fx["csv"]), "--group-by", "load", "--max-force-error",
              "1e6", "--max-torque-error", "1e6", "--serial", "SN1", "--history-dir", str(out["history"])])
        assert main(["plan", "--urdf", str(out["arm"]), "--poses", "6", "--candidates", "100", "--load", "none",
                     "--load", "tool:1@0.03,0,0.04", "-o", str(out["plan"])]) == 0
        # Through the library: `fit --family mlp` writes the affine model when a 20-iteration network loses to it.
        from ftcal import load_dataset, save_model
        from ftcal.core.mlp import MLPModel

        save_model(MLPModel(hidden=(4,), max_iter=20).fit(load_dataset(fx["csv"], group_by="load")), out["mlp"])
    finally:
        sys.stdout, sys.stderr = old
        quiet.close()
    return out


# ------------------------------------------------------------------ hostile variants


def _special(kind: str):
    def make(path: Path) -> None:
        if kind == "fifo":
            os.mkfifo(path)
        elif kind == "zero":
            os.symlink("/dev/zero", path)
        elif kind == "urandom":
            os.symlink("/dev/urandom", path)
        elif kind == "directory":
            path.mkdir()
        elif kind == "loop":
            os.symlink(path.name + ".other", path)
            os.symlink(path.name, path.with_name(path.name + ".other"))
        elif kind == "dangling":
            os.symlink(path.name + ".missing", path)
    return make


def _bytes(data: bytes):
    return lambda path: path.write_bytes(data)


def _nested(kind: str, depth: int) -> bytes:
    if kind == "json":
        return ('{"format": "ftcal-model", "x": ' + "[" * depth + "]" * depth + "}").encode()
    if kind == "xml":
        return ('<group name="modelClassParams">' + "<a>" * depth + "</a>" * depth + "</group>").encode()
    return ("a = " + "[" * depth + "]" * depth + "\n").encode()


def variants(name: str, valid: bytes, text_kind: str, rng: random.Random, n_random: int):
    """(label, writer) pairs: generic hostile files, then random truncations and bit flips of ``valid``."""
    out = [(s, _special(s)) for s in ("fifo", "zero", "urandom", "directory", "loop", "dangling")]
    out += [("empty", _bytes(b"")), ("nul", _bytes(b"\0" * 4096)), ("garbage", _bytes(rng.randbytes(20000))),
            ("one-huge-line", _bytes(b"x" * 3_000_000)), ("bom-only", _bytes(b"\xef\xbb\xbf")),
            ("utf16", _bytes(valid.decode("utf-8", "replace").encode("utf-16"))),
            ("latin1", _bytes(valid.decode("utf-8", "replace").replace("u1", "\u00e91").encode("latin-1", "replace")))]
    if text_kind in ("json", "xml", "toml"):
        out += [(f"nested-{d}", _bytes(_nested(text_kind, d))) for d in (100, 10_000, 1_000_000)]
    for i in range(n_random):
        cut = rng.randrange(len(valid))
        out.append((f"truncated-{i}", _bytes(valid[:cut])))
    for i in range(n_random):
        data = bytearray(valid)
        for _ in range(rng.choice((1, 1, 4, 32))):
            k = rng.randrange(len(data))
            data[k] ^= 1 << rng.randrange(8)
        out.append((f"bitflip-{i}", _bytes(bytes(data))))
    return out


def resealed(text: str) -> bytes:
    """``text`` with its sha256 field recomputed: an attacker edits the file and fixes the digest too."""
    from ftcal.files.model_json import digest

    try:
        d = json.loads(text)
        if isinstance(d, dict) and "sha256" in d:
            d["sha256"] = digest(d)
            return json.dumps(d).encode("utf-8", "surrogatepass")
    except (ValueError, TypeError):
        pass
    return text.encode("utf-8", "surrogatepass")


def model_json_variants(valid: bytes, rng: random.Random):
    """Semantic attacks on an ftcal JSON model (digest resealed): hostile names and units, extreme numbers, bad ranges."""
    out = []

    def put(label, change):
        d = json.loads(valid)
        try:
            change(d)
        except (KeyError, IndexError, TypeError):
            return
        out.append((label, _bytes(resealed(json.dumps(d)))))

    def find(d, key):
        if isinstance(d, dict):
            if key in d:
                yield d
            for v in d.values():
                yield from find(v, key)
        elif isinstance(d, list):
            for v in d:
                yield from find(v, key)

    for i, hostile in enumerate(HOSTILE_NAMES):
        for key in ("input_names", "output_names", "inputs", "outputs", "input_units", "output_units", "name",
                    "unit", "units"):
            def rename(d, key=key, hostile=hostile):
                for holder in find(d, key):
                    value = holder[key]
                    holder[key] = [hostile] * len(value) if isinstance(value, list) else hostile
            put(f"hostile-{key}-{i}", rename)
    for number in ("NaN", "Infinity", "1e308", "-1e308", "1e-320", "123456789012345678901234567890", "true",
                   '"7"', "null", "[]", "{}"):
        text = valid.decode()
        spots = [m.start() for m in re.finditer(r"-?\d+\.\d+(e[-+]?\d+)?", text)]
        for j in rng.sample(spots, min(3, len(spots))):
            m = re.match(r"-?\d+\.\d+(e[-+]?\d+)?", text[j:])
            out.append((f"number-{number}-{j}", _bytes(resealed(text[:j] + number + text[j + m.end():]))))
    for key in ("range",):
        def swap(d, key=key):
            for holder in find(d, key):
                value = holder[key]
                holder[key] = value[::-1] if isinstance(value, list) else value
        put(f"swapped-{key}", swap)
    for key in ("degree", "na", "nb"):
        for value in (-1, 0, 11, 51, 10**12, 2.5, "3"):
            def setv(d, key=key, value=value):
                for holder in find(d, key):
                    holder[key] = value
            put(f"{key}={value}", setv)
    return out


def payload_variants(valid: bytes):
    out = []
    for i, hostile in enumerate(HOSTILE_NAMES):
        d = json.loads(valid)
        d["frame"] = hostile
        out.append((f"hostile-frame-{i}", _bytes(resealed(json.dumps(d)))))
    for key in ("mass", "gravity"):
        for value in (-1.0, 0.0, 1e308, "NaN", None, [1, 2]):
            text = json.dumps({**json.loads(valid), key: value}).replace('"NaN"', "NaN")
            out.append((f"{key}={value}", _bytes(resealed(text))))
    return out


def paper_xml_variants(valid: bytes):
    text = valid.decode()
    out = []
    for param, values in (("np", ("0", "11", "-1", "x", "1e3")), ("nu", ("0", "70", "100000", "2")),
                          ("ny", ("0", "1000000")), ("na", ("-1", "51")), ("nb", ("51", "99999999999"))):
        for value in values:
            out.append((f"{param}={value}", _bytes(re.sub(rf'(name="{param}">)[^<]*', rf"\g<1>{value}", text,
                                                          count=1).encode())))
    out.append(("billion-laughs", _bytes(b'<?xml version="1.0"?><!DOCTYPE g [<!ENTITY a "aaaaaaaaaa">'
                                         + b"".join(b'<!ENTITY %c "%s">' % (98 + i, (b"&%c;" % (97 + i)) * 10)
                                                    for i in range(9))
                                         + b']><group name="modelClassParams">&j;</group>')))
    out.append(("external-entity", _bytes(b'<?xml version="1.0"?><!DOCTYPE g [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
                                          b'<group name="modelClassParams"><param name="np">&x;</param></group>')))
    out.append(("row-nan", _bytes(re.sub(r"(row1\">\()[^ )]*", r"\g<1>nan", text, count=1).encode())))
    out.append(("row-1e309", _bytes(re.sub(r"(row1\">\()[^ )]*", r"\g<1>1e309", text, count=1).encode())))
    return out


def table_variants(valid: bytes, rng: random.Random):
    text = valid.decode()
    header, *rows = text.splitlines()
    out = [("header-only", _bytes((header + "\n").encode())),
           ("duplicate-column", _bytes(text.replace("u2", "u1", 1).encode())),
           ("million-columns", _bytes((",".join(f"c{i}" for i in range(10**6)) + "\n1\n").encode())),
           ("20k-columns", _bytes((",".join(f"c{i}" for i in range(20_000)) + "\n" + ",".join("1" * 20_000) + "\n"
                                   ).encode())),
           ("quoted-newline-name", _bytes(text.replace("u1", '"u\n1"', 1).encode())),
           ("crlf", _bytes(text.replace("\n", "\r\n").encode())),
           ("bom", _bytes(b"\xef\xbb\xbf" + valid))]
    for i, hostile in enumerate(HOSTILE_NAMES[:8]):
        out.append((f"hostile-column-{i}", _bytes(text.replace("Fx", '"' + hostile.replace('"', '""') + '"', 1)
                                                  .encode("utf-8", "surrogateescape"))))
    for value in ("nan", "inf", "-inf", "1e308", "-1e308", "1e400", "", "abc", "0x10", "1,5", "true", "1e-400"):
        k = rng.randrange(len(rows))
        cells = rows[k].split(",")
        cells[rng.randrange(7)] = value
        out.append((f"cell-{value or 'empty'}", _bytes("\n".join([header, *rows[:k], ",".join(cells),
                                                                  *rows[k + 1:]]).encode() + b"\n")))
    out.append(("ragged-row", _bytes((text + "1,2,3\n").encode())))
    out.append(("constant-inputs", _bytes("\n".join([header] + [re.sub(r"^[^,]*,[^,]*", "1,1", r) for r in rows])
                                          .encode() + b"\n")))
    return out


def urdf_variants():
    out = []
    link = '<link name="{n}"><inertial><mass value="{m}"/><inertia ixx="{a}" ixy="{b}" ixz="0" iyy="{c}" iyz="0" izz="{d}"/></inertial></link>'
    for m, a, b, c, d in (("nan", 1, 0, 1, 1), ("-1", 1, 0, 1, 1), ("inf", 1, 0, 1, 1), ("heavy", 1, 0, 1, 1),
                          ("1", "nan", 0, 1, 1), ("1", -1, 0, 1, 1), ("1", 0.1, 0.5, 0.1, 0.1),
                          ("1", 10, 0, 0.1, 0.1), ("1e308", 1e308, 0, 1e308, 1e308), ("0", 0, 0, 0, 0)):
        out.append((f"inertial-{m}-{a}-{b}-{c}", _bytes(URDF.replace(
            '<link name="forearm"><inertial><origin xyz="0.2 0 0"/><mass value="1.5"/>\n'
            '    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>',
            link.format(n="forearm", m=m, a=a, b=b, c=c, d=d)).encode())))
    out.append(("two-parents", _bytes(URDF.replace("</robot>", '<joint name="extra" type="fixed"><parent link="base"/>'
                                                   '<child link="forearm"/></joint></robot>').encode())))
    out.append(("loop", _bytes(URDF.replace("</robot>", '<joint name="back" type="fixed"><parent link="forearm"/>'
                                            '<child link="base"/></joint></robot>').encode())))
    out.append(("self-loop", _bytes(URDF.replace("</robot>", '<link name="x"/><joint name="s" type="fixed">'
                                                 '<parent link="x"/><child link="x"/></joint></robot>').encode())))
    for i, hostile in enumerate(HOSTILE_NAMES[:6]):
        safe = hostile.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;").replace("\0", "")
        out.append((f"hostile-link-{i}", _bytes(URDF.replace('"forearm"', f'"{safe}"').encode("utf-8", "replace"))))
    return out


def _hdf5(valid: bytes, change):
    """A copy of the valid v7.3 file, changed with h5py (links, loops, absurd shapes)."""
    def make(path: Path) -> None:
        import h5py

        path.write_bytes(valid)
        with h5py.File(path, "r+") as fh:
            change(fh, path)
    return make


def mat73_variants(valid: bytes):
    """Link loops, links out of the file, shared links, deep nesting and absurd shapes in a v7.3 (HDF5) log."""
    import h5py
    import numpy as np

    root, fts = "/robot_logger_device", "/robot_logger_device/FTs"

    def soft(fh, _, name, target):
        fh[fts][name] = h5py.SoftLink(target)

    def cycle(fh, _):
        soft(fh, _, "x", f"{fts}/y")
        soft(fh, _, "y", f"{fts}/x")

    def hard(fh, _, names):
        for name in names:
            fh[fts][name] = fh[fts]

    def chain(fh, _, depth=24):
        groups = [fh[f"{fts}/arm_ft"]] + [fh["#refs#"].create_group(f"g{i}") for i in range(depth)]
        for upper, lower in zip(groups[:-1], groups[1:]):
            upper["a"], upper["b"] = lower, lower

    def deep(fh, _, depth=100):
        group = fh[fts]
        for i in range(depth):
            group = group.create_group(f"d{i}")

    def ref_loop(fh, _):
        cell = fh["#refs#"].create_dataset("loop", shape=(1, 2), dtype=h5py.ref_dtype)
        cell[0, 0] = cell[0, 1] = cell.ref
        cell.attrs["MATLAB_class"] = np.bytes_("cell")
        del fh[root]["description_list"]
        fh[root]["description_list"] = cell

    def external(fh, path, target):
        if target == "fifo":
            target = str(path) + ".fifo"
            os.mkfifo(target)
        del fh[f"{fts}/arm_ft/data"]
        fh[f"{fts}/arm_ft"]["data"] = h5py.ExternalLink(target, "/robot_logger_device/FTs/arm_ft/data")

    def huge(fh, _, shape):
        del fh[f"{fts}/arm_ft/data"]
        fh[f"{fts}/arm_ft"].create_dataset("data", shape=shape, dtype="f8", chunks=(1, shape[1]))

    return [("soft-self", _hdf5(valid, lambda fh, p: soft(fh, p, "x", f"{fts}/x"))),
            ("soft-cycle", _hdf5(valid, cycle)),
            ("soft-to-root", _hdf5(valid, lambda fh, p: soft(fh, p, "x", root))),
            ("soft-dangling", _hdf5(valid, lambda fh, p: soft(fh, p, "x", "/nowhere"))),
            ("hard-self", _hdf5(valid, lambda fh, p: hard(fh, p, ["self"]))),
            ("hard-self-twice", _hdf5(valid, lambda fh, p: hard(fh, p, ["a", "b"]))),
            ("shared-chain-24", _hdf5(valid, chain)),
            ("nested-100", _hdf5(valid, deep)),
            ("ref-loop", _hdf5(valid, ref_loop)),
            ("external-dev-zero", _hdf5(valid, lambda fh, p: external(fh, p, "/dev/zero"))),
            ("external-fifo", _hdf5(valid, lambda fh, p: external(fh, p, "fifo"))),
            ("external-valid-file", _hdf5(valid, lambda fh, p: external(fh, p, "/etc/hostname"))),
            ("declares-1e12", _hdf5(valid, lambda fh, p: huge(fh, p, (10**12, 6)))),
            ("declares-1e9", _hdf5(valid, lambda fh, p: huge(fh, p, (10**9, 6))))]


def _v5_element(kind: int, data: bytes) -> bytes:
    import struct

    return struct.pack("<II", kind, len(data)) + data + bytes(-len(data) % 8)


def mat5_variants(valid: bytes, rng: random.Random, n_random: int):
    """Absurd declared sizes, truncations and deflate bombs in a v5 log (scipy writes one deflated variable)."""
    import struct
    import zlib

    header = valid[:128]
    inner = zlib.decompress(valid[136:136 + struct.unpack("<I", valid[132:136])[0]])

    def packed(matrix: bytes) -> bytes:
        data = zlib.compress(matrix)
        return header + struct.pack("<II", 15, len(data)) + data

    def with_dims(dims) -> bytes:  # the struct's dimensions subelement sits at bytes 24..40 of the matrix
        return inner[:32] + struct.pack("<ii", *dims) + inner[40:]

    out = [("dims-1e10", _bytes(packed(with_dims((10**5, 10**5))))),
           ("dims-2e9", _bytes(packed(with_dims((2 * 10**4, 10**5 + 1))))),
           ("dims-negative", _bytes(packed(with_dims((-1, 1))))),
           ("inner-bytes-4e9", _bytes(packed(inner[:4] + struct.pack("<I", 2**32 - 8) + inner[8:]))),
           ("outer-bytes-2e9", _bytes(valid[:132] + struct.pack("<I", 2**31) + valid[136:])),
           ("uncompressed", _bytes(header + inner)),
           ("uncompressed-dims-1e12", _bytes(header + with_dims((10**6, 10**6)))),
           ("uncompressed-bytes-4e9", _bytes(header + inner[:4] + struct.pack("<I", 2**32 - 8) + inner[8:])),
           ("deflate-bomb", _bytes(packed(struct.pack("<II", 14, 2**32 - 8) + inner[8:40] + bytes(64 * 2**20))))]
    nested = _v5_element(14, b"")
    for _ in range(200):  # a 1 x 1 struct with one field, 200 deep
        body = (_v5_element(6, struct.pack("<II", 2, 0)) + _v5_element(5, struct.pack("<ii", 1, 1))
                + _v5_element(1, b"") + _v5_element(5, struct.pack("<i", 8)) + _v5_element(1, b"a".ljust(8, b"\0"))
                + nested)
        nested = struct.pack("<II", 14, len(body)) + body
    out.append(("nested-200", _bytes(header + nested)))
    flat = header + inner
    for i in range(n_random):
        out.append((f"uncompressed-truncated-{i}", _bytes(flat[:rng.randrange(len(flat))])))
    return out


def cases(fx: dict[str, Path], work: Path, rng: random.Random, n_random: int) -> list[dict]:
    """Every case: the hostile file to create, the command lines that read it, and the outputs."""
    out = []

    def add(kind: str, source: Path, label: str, writer, commands, suffix: str | None = None):
        name = f"{kind}-{label}".replace("/", "_")[:80] + (suffix if suffix is not None else source.suffix)
        for j, make_argv in enumerate(commands):
            folder = work / f"{len(out):05d}"
            path = folder / name
            argv, outputs, check = make_argv(path, folder)
            out.append({"kind": kind, "label": label, "command": argv[0], "folder": str(folder), "path": str(path),
                        "writer": (kind, label), "argv": argv, "outputs": outputs, "check": check})
            WRITERS[(kind, label)] = writer

    def o(folder, name):
        return str(folder / "out" / name)

    table_cmds = [lambda p, f: (["fit", str(p), "--degree", "2", "-o", o(f, "m.json")], [o(f, "m.json")], None),
                  lambda p, f: (["evaluate", str(fx["model"]), str(p)], [], None),
                  lambda p, f: (["predict", str(fx["model"]), str(p), "-o", o(f, "p.csv")], [o(f, "p.csv")], None)]
    model_cmds = [lambda p, f: (["info", str(p)], [], None),
                  lambda p, f: (["convert", str(p), "--to", "c", "--name", "cal", "-o", o(f, "c") + "/"],
                                [o(f, "c/cal.h"), o(f, "c/cal.c")], "c"),
                  lambda p, f: (["convert", str(p), "--to", "c-runtime", "--name", "cal", "-o", o(f, "rt.h")],
                                [o(f, "rt.h")], "c-runtime"),
                  lambda p, f: (["evaluate", str(p), str(fx["csv"])], [], None),
                  lambda p, f: (["convert", str(p), "--to", "onnx", "-o", o(f, "m.onnx")], [o(f, "m.onnx")], None),
                  lambda p, f: (["convert", str(p), "--to", "paper-xml", "-o", o(f, "m.xml")], [o(f, "m.xml")], None)]
    affine_cmds = [lambda p, f: (["convert", str(p), "--to", "wbd", "--sensor", "ft", "-o", o(f, "w.xml")],
                                 [o(f, "w.xml")], "xml")]
    payload_cmds = [lambda p, f: (["convert", str(p), "--to", "ros-yaml", "-o", o(f, "p.yaml")], [o(f, "p.yaml")],
                                  "yaml"),
                    lambda p, f: (["convert", str(fx["model"]), "--to", "c-runtime", "--name", "cal",
                                   "--payload-file", f"tool={p}", "-o", o(f, "rt.h")], [o(f, "rt.h")], "c-runtime"),
                    lambda p, f: (["compensate", str(p), str(fx["poses"]), "--orientation", "qx,qy,qz,qw",
                                   "-o", o(f, "c.csv")], [o(f, "c.csv")], None),
                    lambda p, f: (["live", "--replay", str(fx["live"]), "--orientation", "qx,qy,qz,qw",
                                   "--tool", f"tool={p}", "-o", o(f, "l.parquet")], [o(f, "l.parquet")], None)]
    urdf_cmds = [lambda p, f: (["sensors", "--urdf", str(p), "--no-cache"], [], None),
                 lambda p, f: (["expected", "--urdf", str(p), "--joints", str(fx["joints"]), "--no-cache",
                                "-o", o(f, "e.csv")], [o(f, "e.csv")], None)]
    bag_cmds = [lambda p, f: (["topics", str(p)], [], None),
                lambda p, f: (["dataset", str(p), "--wrench-topic", "/ft", "--temperature-topic", "/temp",
                               "-o", o(f, "d.parquet")], [o(f, "d.parquet")], None)]

    csv = fx["csv"].read_bytes()
    for label, writer in variants("csv", csv, "csv", rng, n_random) + table_variants(csv, rng):
        add("table", fx["csv"], label, writer, table_cmds)
    for label, writer in variants("parquet", fx["parquet"].read_bytes(), "bin", rng, n_random):
        add("parquet", fx["parquet"], label, writer, table_cmds[:1])
    model = fx["model"].read_bytes()
    for label, writer in variants("model", model, "json", rng, n_random) + model_json_variants(model, rng):
        add("model", fx["model"], label, writer, model_cmds[:3] if label.startswith(("hostile", "number"))
            else model_cmds[:1] + model_cmds[2:3])
    affine = fx["affine"].read_bytes()
    for label, writer in model_json_variants(affine, rng)[:40]:
        add("affine", fx["affine"], label, writer, affine_cmds)
    xml = fx["xml"].read_bytes()
    for label, writer in variants("xml", xml, "xml", rng, n_random) + paper_xml_variants(xml):
        add("paper-xml", fx["xml"], label, writer, model_cmds[:2])
    payload = fx["payload"].read_bytes()
    for label, writer in variants("payload", payload, "json", rng, n_random // 2) + payload_variants(payload):
        add("payload", fx["payload"], label, writer, payload_cmds)
    urdf = fx["urdf"].read_bytes()
    for label, writer in variants("urdf", urdf, "xml", rng, n_random // 2) + urdf_variants():
        add("urdf", fx["urdf"], label, writer, urdf_cmds)
    for kind in ("ros1", "mcap-file", "db3-file"):
        for label, writer in variants(kind, fx[kind].read_bytes(), "bin", rng, n_random):
            add(kind, fx[kind], label, writer, bag_cmds)
    for label, writer in variants("parquet-plain", fx["parquet-plain"].read_bytes(), "bin", rng, n_random):
        add("parquet-plain", fx["parquet-plain"], label, writer, table_cmds[:1])
    mat_cmds = [lambda p, f: (["dataset", str(p), "--urdf", str(fx["urdf"]), "--sensor", "arm_ft", "--no-cache",
                               "-o", o(f, "d.parquet")], [o(f, "d.parquet")], None)]
    mat73, mat5 = fx["mat-v73"].read_bytes(), fx["mat-v5"].read_bytes()
    for label, writer in variants("mat-v73", mat73, "bin", rng, n_random) + mat73_variants(mat73):
        add("mat-v73", fx["mat-v73"], label, writer, mat_cmds)
    for label, writer in variants("mat-v5", mat5, "bin", rng, n_random) + mat5_variants(mat5, rng, n_random):
        add("mat-v5", fx["mat-v5"], label, writer, mat_cmds)

    def add_option_case(command, action, value, base, surface=None):
        folder = work / f"{len(out):05d}"
        argv, outputs = base(folder)
        option = max(action.option_strings, key=len)
        writer, label = (lambda path: None), f"{option}={value}"
        if isinstance(value, tuple):  # a hostile file given as the option's value
            writer, label = _hostile_path(value[1]), f"{option}={value[1]}"
            value = str(folder / f"hostile-{value[1]}{'.csv' if action.dest != 'history_dir' else ''}")
        argv, output_changed = _with_option(argv, action, value)
        if output_changed or action.dest in ("output", "html", "out"):
            outputs = []  # the output went elsewhere (or nowhere): only leftovers are checked
        path = folder / (f"hostile-{label.split('=')[-1]}" + (".csv" if action.dest != "history_dir" else ""))
        out.append({"kind": f"option:{surface or command}", "label": label[:80], "command": command,
                    "folder": str(folder),
                    "path": str(path), "writer": ("option", f"{command} {label}"[:120]), "argv": argv,
                    "outputs": outputs, "check": None})
        WRITERS[("option", f"{command} {label}"[:120])] = writer

    option_cases(fx, add_option_case, o)
    return out


WRITERS: dict = {}


# ------------------------------------------------------------------ every option of every command, from the parser

def base_invocations(fx: dict, o) -> dict:
    """One valid, quick command line per subcommand: each option's hostile values are tried on it.

    ``o(folder, name)`` is an output path in the case's folder. Each entry:
    command -> callable(folder) -> (argv, outputs).
    """
    model, csv = str(fx["model"]), str(fx["csv"])
    pose = ["--orientation", "qx,qy,qz,qw"]
    return {
        "plan": lambda f: (["plan", "--urdf", str(fx["arm"]), "--poses", "6", "--candidates", "100", "--load", "none",
                            "--load", "tool:1@0.03,0,0.04", "-o", o(f, "p.csv")], [o(f, "p.csv")]),
        "sensors": lambda f: (["sensors", "--urdf", str(fx["urdf"])], []),
        "expected": lambda f: (["expected", "--urdf", str(fx["urdf"]), "--joints", str(fx["joints"]), "--no-cache",
                                "-o", o(f, "e.csv")], [o(f, "e.csv")]),
        "topics": lambda f: (["topics", str(fx["mcap-file"])], []),
        "dataset": lambda f: (["dataset", str(fx["mcap-file"]), "--wrench-topic", "/ft", "--joints-topic",
                               "/joint_states", "--no-cache", "-o", o(f, "d.parquet")], [o(f, "d.parquet")]),
        "fit": lambda f: (["fit", csv, "--degree", "2", "-o", o(f, "m.json")], [o(f, "m.json")]),
        "evaluate": lambda f: (["evaluate", model, csv], []),
        "report": lambda f: (["report", model, csv, "-o", o(f, "r.html")], [o(f, "r.html")]),
        "check": lambda f: (["check", "--accept", model, csv, "--group-by", "load", "--max-force-error", "1e6",
                             "--max-torque-error", "1e6"], []),
        "predict": lambda f: (["predict", model, csv, "-o", o(f, "p.csv")], [o(f, "p.csv")]),
        "convert": lambda f: (["convert", model, "--to", "paper-xml", "-o", o(f, "m.xml")], [o(f, "m.xml")]),
        "info": lambda f: (["info", str(fx["mlp"])], []),
        "payload": lambda f: (["payload", str(fx["poses"]), *pose, "-o", o(f, "p.json")], [o(f, "p.json")]),
        "compensate": lambda f: (["compensate", str(fx["payload"]), str(fx["poses"]), *pose, "-o", o(f, "c.csv")],
                                 [o(f, "c.csv")]),
        "simulate": lambda f: (["simulate", str(fx["plan"]), "--urdf", str(fx["arm"]), "--load", "none", "--load",
                                "tool:1@0.03,0,0.04", "--hold", "0.2", "--rate", "50", "--format", "table",
                                "-o", o(f, "sim")], [o(f, "sim/truth.json"), o(f, "sim/loads.toml")]),
        "live": lambda f: (["live", "--replay", str(fx["live"]), *pose, "-o", o(f, "l.parquet")], [o(f, "l.parquet")]),
    }


def extra_bases(fx: dict, o) -> dict:
    """Further base invocations of a subcommand, each a surface of its own: surface -> (command, callable(folder)).
    Every option of the command is driven on each of them too."""
    model = str(fx["model"])
    port = fx.get("peer_port", PEER_PORT)
    return {
        "convert --to c-runtime": ("convert", lambda f: (["convert", model, "--to", "c-runtime", "--name", "cal",
                                                          "-o", o(f, "rt.h")], [o(f, "rt.h")])),
        # A real Zenoh node on 127.0.0.1 (an ephemeral port), connected to the harness's peer (:func:`peer`), which
        # publishes wrenches, an IMU and a temperature: each option's hostile values meet real traffic.
        "live --zenoh": ("live", lambda f: (["live", "--zenoh", "--listen", "tcp/127.0.0.1:0", "--connect",
                                             f"tcp/127.0.0.1:{port}", "--imu-topic", "/imu", "--temperature-topic",
                                             "/temperature", "--tool", f"tool={fx['payload']}", "--duration",
                                             str(ZENOH_CASE_S), "--state", o(f, "state.json")], [])),
    }


# The harness's Zenoh peer (`python tests/helpers/adversarial.py --peer PORT`) listens on a free port (run() picks it).
PEER_PORT = 7491  # only for uncovered(), which builds no case
ZENOH_CASE_S = 0.5  # each `live --zenoh` case runs this long (its --duration)


def peer(port: int) -> None:
    """A Zenoh peer on 127.0.0.1:``port`` publishing CDR ``WrenchStamped`` on ``ft/raw`` (a still sensor with the
    fixture's tool), ``sensor_msgs/msg/Imu`` on ``imu`` (level) and ``Temperature`` on ``temperature`` at 200 Hz,
    stamped by the wall clock, until killed."""
    import time

    import zenoh

    from ftcal.live.cdr import encode_stamped
    from ftcal.live.zenoh_node import zenoh_config

    session = zenoh.open(zenoh_config(listen=(f"tcp/127.0.0.1:{port}",)))
    wrench, imu, temperature = (session.declare_publisher(k) for k in ("ft/raw", "imu", "temperature"))
    level = [0.0, 0.0, 0.0, 1.0] + [0.0] * 21 + [0.0, 0.0, 9.81] + [0.0] * 9
    while True:
        now = time.time_ns()
        wrench.put(encode_stamped(now, "ft", [1.0, -2.0, 0.5 - 1.2 * 9.81, 0.1, 0.0, -0.1]))
        imu.put(encode_stamped(now, "imu", level))
        temperature.put(encode_stamped(now, "t", [30.0, 0.0]))
        time.sleep(0.005)


# Surfaces driven with the EXTRA_VALUES as well (issue 39: every option of simulate and convert --to c-runtime).
EXTRA_SURFACES = ("simulate", "convert --to c-runtime", "live", "live --zenoh")
# Values not tried on a surface, each with the reason: they run as asked.
SKIPPED_VALUES = {
    ("live --zenoh", "--duration", "1e308"): "runs as long as asked (until Ctrl-C or SIGTERM: tests/live/test_live_zenoh.py)",
    ("live --zenoh", "--duration", "inf"): "runs as long as asked, as 1e308",
}
EXTRA_VALUES = {
    "number": ("inf", "-inf", "-1e308", "1e-320", "", "\x1b[2J"),
    "structured": ("inf,inf", "-1,-1", "nan,nan,nan", "\x07\x1b[2J", "k" * 5000),
    "columns": ("\x1b[2J", "u1,\x00"),
    "text": ("\x1b[2J\x07", "\t\r", "-", "\x00", "\u202epwned", "k" * 100000),
    "choice": ("", "\x1b[2J"),
    "path": (("path", "zero"), ("path", "empty"), ("path", "dotdot"), ("path", "device")),
}


# Options not driven with hostile values here, each with the reason; any other option without a generator fails.
EXEMPT = {
    ("demo", "--quick"): "runs the whole demo (minutes); tests/e2e/test_demo.py",
    ("demo", "--out"): "runs the whole demo (minutes); tests/e2e/test_demo.py",
    ("demo", "--scenario"): "runs the whole demo (minutes); tests/e2e/test_demo.py",
    ("demo", "--seed"): "runs the whole demo (minutes); tests/e2e/test_demo.py",
    ("demo", "--variant"): "runs the whole closed-loop demo (minutes); tests/e2e/test_closed_loop.py",
    ("demo", "--seeds"): "runs the whole closed-loop demo (minutes); tests/e2e/test_closed_loop.py",
}
NUMBER_TYPES = {"int", "nonnegative_int", "positive_int", "positive_float", "finite_float", "fraction"}
NUMBER_VALUES = ("0", "-1", "nan", "1e308", "x")
PAIR_TYPES = {"joint_pin", "joint_range", "frame_pair", "degree_value", "lambda_grid", "noise_pair", "penalty_list",
              "safe_name", "pair", "mistake", "tool_spec", "switch_spec", "float_list", "signed_list"}
PAIR_VALUES = ("", "x", "nan:1", "1e308,1e308", "1,1")
COLUMN_VALUES = ("", "nope", "u1,u1", "u1,u2,u3,u4,u5,u6,u7", "f\npwned")
TEXT_VALUES = ("", "nope", "f\nwrote 1 file", "k" * 3000)
PATH_WORDS = (".", "PATH", "DIR", "DATA", "MODEL", "PAGE", "CSV", "JSON", "LINK")
PATH_VALUES = ("fifo", "directory", "missing", "garbage")


def _option_kind(action) -> str | None:
    import argparse

    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return "flag"
    if action.choices:
        return "choice"
    name = getattr(action.type, "__name__", None) if action.type else None
    if name in NUMBER_TYPES:
        return "number"
    if name == "column_list":
        return "columns"
    if name in PAIR_TYPES:
        return "structured"
    if name is None:
        text = f"{action.metavar or ''} {action.dest}"
        return "path" if any(w in text for w in PATH_WORDS) or action.dest in ("output", "html", "out") else "text"
    return None  # a type this generator does not know: a new option needs a generator


def parser_options() -> dict[str, list]:
    """Every option (its argparse action) of every subcommand, read from ftcal's own parser."""
    import argparse

    from ftcal.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {name: [a for a in sp._actions if a.option_strings and "--help" not in a.option_strings]
            for name, sp in sub.choices.items()}


def uncovered(fx: dict | None = None) -> list[str]:
    """Subcommands without a base invocation and options without a generator (nor an exemption)."""
    bases = base_invocations(fx or {k: Path(k) for k in ("model", "csv", "arm", "urdf", "joints", "mcap-file", "mlp",
                                                          "poses", "payload", "plan", "live")}, lambda f, n: n)
    missing = []
    for command, actions in parser_options().items():
        if command not in bases and not all((command, max(a.option_strings, key=len)) in EXEMPT for a in actions):
            missing.append(f"{command}: no base invocation")
        for a in actions:
            option = max(a.option_strings, key=len)
            if (command, option) not in EXEMPT and _option_kind(a) is None:
                missing.append(f"{command} {option}: no generator for type {getattr(a.type, '__name__', a.type)}")
    return missing


def _hostile_path(kind: str):
    def make(path: Path) -> None:
        if kind == "fifo":
            os.mkfifo(path)
        elif kind == "directory":
            path.mkdir()
        elif kind == "garbage":
            path.write_bytes(b"\x00garbage\xff" * 100)
        elif kind == "zero":
            os.symlink("/dev/zero", path)
        elif kind == "empty":
            path.write_bytes(b"")
        elif kind == "dotdot":  # a symlink to the folder above: a directory reached through a link
            os.symlink("..", path)
        elif kind == "device":  # a character device node like /dev/null, made here (root may): never replaced
            import stat

            try:
                os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
            except PermissionError:
                os.mkfifo(path)
    return make


def option_cases(fx: dict, add_case, o) -> None:
    """For every option of every command: its hostile values on the command's base invocation."""
    problems = uncovered(fx)
    if problems:
        raise SystemExit("adversarial.py: " + "; ".join(problems))
    bases = {command: (command, base) for command, base in base_invocations(fx, o).items()}
    bases.update(extra_bases(fx, o))
    options = parser_options()
    for surface, (command, base) in bases.items():
        for action in options[command]:
            option = max(action.option_strings, key=len)
            if (command, option) in EXEMPT:
                continue
            kind = _option_kind(action)
            if kind == "flag":
                values = [None]
            elif kind == "choice":
                values = ["bogus", *[c for c in action.choices if c != action.default][:2]]
            elif kind == "number":
                values = list(NUMBER_VALUES)
            elif kind == "columns":
                values = list(COLUMN_VALUES)
            elif kind == "structured":
                values = list(PAIR_VALUES)
            elif kind == "path":
                values = [("path", v) for v in PATH_VALUES]
            else:
                values = list(TEXT_VALUES)
            if surface in EXTRA_SURFACES and kind != "flag":
                values += [v if isinstance(v, tuple) else v.encode().decode("unicode_escape")
                           for v in EXTRA_VALUES["text" if kind not in EXTRA_VALUES else kind]]
            for value in values:
                if isinstance(value, str) and (surface, option, value) in SKIPPED_VALUES:
                    continue
                add_case(command, action, value, base, surface)


def _with_option(argv: list, action, value) -> tuple[list, bool]:
    """``argv`` with the option set to ``value`` (replacing its first occurrence); True if it replaced an output."""
    strings = set(action.option_strings)
    argv = list(argv)
    replaced = False
    for i, word in enumerate(argv):
        if word in strings:
            if value is None:
                return argv, False
            argv[i + 1] = value
            replaced = True
            break
    if not replaced:
        argv += [max(action.option_strings, key=len)] + ([] if value is None else [value])
    return argv, replaced and action.dest in ("output", "html", "out")


# ------------------------------------------------------------------ running


def worker() -> None:
    """Run cases read from stdin (one JSON line each), in this process; answer one JSON line each."""
    import contextlib
    import io
    import traceback
    import warnings

    from ftcal.cli import main

    warnings.simplefilter("default")
    # As the ftcal command runs: iDynTree's SWIG bindings warn on import (pyproject.toml ignores the same).
    warnings.filterwarnings("ignore", message=r"builtin type .* has no __module__ attribute",
                            category=DeprecationWarning)
    for line in sys.stdin:
        case = json.loads(line)
        out, err = io.StringIO(), io.StringIO()
        escaped = None
        os.chdir(case["folder"])
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(case["argv"])
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 2
            except BaseException:  # noqa: BLE001 - what the runner classifies
                code, escaped = None, traceback.format_exc()
        try:  # `live --rt-priority N` made this thread SCHED_FIFO (root may): the next case runs as usual
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except (AttributeError, OSError):
            pass
        print(json.dumps({"code": code, "stderr": err.getvalue()[-300000:], "stdout": out.getvalue()[-4000:],
                          "escaped": escaped}), flush=True)


class Worker:
    def __init__(self, env: dict) -> None:
        self.env = env
        self.start()

    def start(self) -> None:
        self.proc = subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=self.env)

    def run(self, case: dict, timeout: float) -> dict:
        self.proc.stdin.write(json.dumps(case) + "\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if ready:
            line = self.proc.stdout.readline()
            if line:
                return json.loads(line)
        if not ready:  # no answer: a hang; the worker is replaced
            self.stop()
            self.start()
            return {"hang": True}
        code = self.stop()
        self.start()
        return {"signal": -code if code < 0 else None, "code": code}

    def stop(self) -> int:
        """End the worker process and close its pipes; its exit code."""
        self.proc.kill()
        code = self.proc.wait()
        for pipe in (self.proc.stdin, self.proc.stdout):
            try:
                pipe.close()
            except OSError:
                pass  # the other end is gone
        return code


ERROR_LINE = re.compile(r"^ftcal( [a-z-]+)?: error: ")
# Python's own words where a user should see ftcal's: numpy reprs, runtime warnings.
NOISE = ("np.float64(", "np.int64(", "array([", "RuntimeWarning", "DeprecationWarning")
NAN_WORD = re.compile(r"(?<![A-Za-z_])(nan|NaN|-?inf|-?Infinity)(?![A-Za-z_])")


def classify(case: dict, result: dict) -> tuple[str, str]:
    """(outcome, detail) of one case (see the module docstring)."""
    if result.get("hang"):
        return "hang", ""
    if "signal" in result:
        return "crash", f"signal {result['signal']}" if result["signal"] else f"worker exit {result['code']}"
    if case["label"].endswith("=device"):
        import stat

        mode = os.lstat(case["path"]).st_mode if os.path.lexists(case["path"]) else 0
        if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
            return "lost", "the device node given as a path was replaced or removed"
    if result.get("escaped"):
        return "traceback", result["escaped"].strip().splitlines()[-1][:200]
    code, stderr, stdout = result["code"], result["stderr"], result.get("stdout", "")
    leftovers = [str(p) for p in Path(case["folder"]).rglob("*.tmp")]
    noise = [w for w in NOISE if w in stderr or w in stdout]
    if noise:
        return "noise", f"{noise[0]!r} in the output: {stderr.strip()[-200:]}"
    if code in (0, 1) and "PASS" in stdout.split() and NAN_WORD.search(stdout):
        return "verdict", "PASS printed beside a non-finite metric"
    if code == 1 and case["command"] == "check":  # findings or FAIL: a verdict, not an error
        code = 0
    if code == 0:
        missing = [p for p in case["outputs"] if not Path(p).exists()]
        if missing or leftovers:
            return "lost", f"missing {missing} leftovers {leftovers}"
        nonfinite = [p for p in case["outputs"] if Path(p).suffix in (".csv", ".json")
                     and NAN_WORD.search(Path(p).read_text(errors="replace"))]
        if nonfinite:
            return "nonfinite", f"exit 0 with NaN/inf in {nonfinite}"
        return check_injection(case)
    if code == 2:
        lines = [line for line in stderr.strip().splitlines() if line]
        errors = [line for line in lines if ERROR_LINE.match(line)]
        if "Traceback" in stderr or len(errors) != 1 or not lines or lines[-1] != errors[0]:
            return "traceback", " | ".join(lines[-3:])[:300]
        written = [p for p in case["outputs"] if Path(p).exists()]
        if written or leftovers:
            return "lost", f"failure left {written + leftovers}"
        return "clean", errors[0][:200]
    return "traceback", f"exit {code}: {stderr.strip()[-200:]}"


def check_injection(case: dict) -> tuple[str, str]:
    """Compile generated C and parse generated YAML/XML: nothing from the file may appear as code or keys."""
    check = case["check"]
    if check == "c":
        folder = Path(case["outputs"][1]).parent
        obj = folder / "cal.o"
        done = subprocess.run(["cc", "-std=c99", "-trigraphs", "-c", "cal.c", "-o", obj.name], cwd=folder,
                              capture_output=True, text=True)
        if done.returncode != 0:
            return "injection", f"generated C does not compile: {done.stderr.strip()[:200]}"
        symbols = subprocess.run(["nm", "--defined-only", "-P", obj.name], cwd=folder, capture_output=True,
                                 text=True).stdout.split("\n")
        names = {line.split()[0] for line in symbols if line.strip()}
        extra = {n for n in names if not n.startswith("cal_")}
        return ("injection", f"symbols {sorted(extra)}") if extra else ("clean", "C compiled, symbols cal_*")
    if check == "c-runtime":
        folder = Path(case["outputs"][0]).parent
        (folder / "use_rt.c").write_text('#include "rt.h"\nint main(void) { cal_state s; cal_output o; double u[64] = {0};'
                                         ' double g[3] = {0, 0, -9.81}; cal_init(&s, 0);'
                                         ' return cal_step(&s, 0.0, u, g, -1, &o) < -1; }\n')
        done = subprocess.run(["cc", "-std=c99", "-trigraphs", "-c", "use_rt.c", "-o", "use_rt.o"], cwd=folder,
                              capture_output=True, text=True)
        if done.returncode != 0:
            return "injection", f"generated C does not compile: {done.stderr.strip()[:200]}"
        symbols = subprocess.run(["nm", "--defined-only", "-P", "-g", "use_rt.o"], cwd=folder, capture_output=True,
                                 text=True).stdout.split("\n")
        names = {line.split()[0] for line in symbols if line.strip()}
        return ("injection", f"global symbols {sorted(names)}") if names != {"main"} else (
            "clean", "C compiled, only main global")
    text = Path(case["outputs"][0]).read_text(encoding="utf-8", errors="replace") if check else ""
    if check == "yaml":
        import yaml

        keys = set(yaml.safe_load(text))
        extra = keys - {"bias", "gripper_com_child_frame_id", "gripper_com_frame_id", "gripper_com_pose",
                        "gripper_mass"}
        return ("injection", f"YAML keys {sorted(extra)}") if extra else ("clean", "YAML keys as expected")
    if check == "xml":
        import xml.etree.ElementTree as ET

        groups = [g.get("name") for g in ET.fromstring("<r>" + text + "</r>")]
        extra = set(groups) - {"FT_SECONDARY_CALIBRATION", "FT_TEMPERATURE_COEFFICIENTS", "FT_OFFSET"}
        return ("injection", f"XML groups {sorted(extra)}") if extra else ("clean", "XML groups as expected")
    return "clean", "exit 0"


def run(sample: int | None = None, workers: int = 2, out: Path | None = None, n_random: int = 12,
        seed: int = 17, timeout: float = TIMEOUT_S, kinds: list[str] | None = None) -> list[dict]:
    """Build the fixtures and cases, run them, return one record per case (``outcome``, ``detail``...).

    ``kinds``: run only the cases of these input kinds (default: all)."""
    rng = random.Random(seed)
    root = Path(tempfile.mkdtemp(prefix="ftcal-adversarial-")) if out is None else out
    fx = make_fixtures(root / "fixtures")
    import socket

    with socket.socket() as s:  # the harness's Zenoh peer (live --zenoh cases): a free port
        s.bind(("127.0.0.1", 0))
        fx["peer_port"] = s.getsockname()[1]
    todo = [c for c in cases(fx, root / "cases", rng, n_random) if kinds is None or c["kind"] in kinds]
    if sample is not None and sample < len(todo):
        todo = random.Random(seed).sample(todo, sample)
    env = {**os.environ, "FTCAL_PROGRESS": "0", "FTCAL_THREADS": "1", "XDG_CACHE_HOME": str(root / "cache")}
    publisher = None
    if any(c["kind"] == "option:live --zenoh" for c in todo):
        publisher = subprocess.Popen([sys.executable, __file__, "--peer", str(fx["peer_port"])], env=env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for case in todo:
        folder = Path(case["folder"])
        (folder / "out").mkdir(parents=True, exist_ok=True)
        WRITERS[tuple(case["writer"])](Path(case["path"]))
    queue = collections.deque(todo)
    lock = threading.Lock()
    records = []

    def drain() -> None:
        w = Worker(env)
        try:
            while True:
                with lock:
                    if not queue:
                        return
                    case = queue.popleft()
                result = w.run({k: case[k] for k in ("argv", "folder")}, timeout)
                outcome, detail = classify(case, result)
                with lock:
                    records.append({**{k: case[k] for k in ("kind", "label", "command", "argv")},
                                    "outcome": outcome, "detail": detail})
        finally:
            w.stop()

    threads = [threading.Thread(target=drain) for _ in range(workers)]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        if publisher is not None:
            publisher.kill()
            publisher.wait()
    if out is None:
        shutil.rmtree(root, ignore_errors=True)
    return records


def summary(records: list[dict]) -> str:
    """A Markdown table: cases per input kind and outcome."""
    outcomes = ("clean", "hang", "crash", "traceback", "injection", "lost", "verdict", "nonfinite", "noise")
    by_kind = collections.defaultdict(collections.Counter)
    for r in records:
        by_kind[r["kind"]][r["outcome"]] += 1
    lines = ["| input kind | cases | " + " | ".join(outcomes) + " |", "|---|---:|" + "---:|" * len(outcomes)]
    for kind in sorted(by_kind):
        c = by_kind[kind]
        lines.append(f"| {kind} | {sum(c.values())} | " + " | ".join(str(c[o]) for o in outcomes) + " |")
    total = collections.Counter(r["outcome"] for r in records)
    lines.append(f"| **all** | **{len(records)}** | " + " | ".join(f"**{total[o]}**" for o in outcomes) + " |")
    clean = total["clean"] / max(len(records), 1)
    return "\n".join(lines) + f"\n\nclean: {100 * clean:.1f} % of {len(records)} cases"


if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:
        worker()
        sys.exit(0)
    if sys.argv[1:2] == ["--peer"]:
        peer(int(sys.argv[2]))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, help="run this many cases, drawn at random (default: all)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--random", type=int, default=12, help="random truncations and bit flips per file")
    parser.add_argument("--out", type=Path, help="keep the fixtures and cases here")
    parser.add_argument("--report", type=Path, help="write every case's outcome as JSON lines here")
    parser.add_argument("--kinds", help="comma-separated input kinds to run (default: all)")
    a = parser.parse_args()
    recs = run(a.sample, a.workers, a.out, a.random, kinds=a.kinds.split(",") if a.kinds else None)
    if a.report:
        a.report.write_text("".join(json.dumps(r) + "\n" for r in recs))
    print(summary(recs))
    for r in recs:
        if r["outcome"] != "clean":
            print(f"{r['outcome']:9} {r['kind']}/{r['label']} {r['command']}: {r['detail']}")
