"""Issue 17, file readers: link loops in HDF5 .mat logs, declared sizes and truncation in v5 .mat logs.

Each test is one class of hostile input; each failed on the main branch before the fix
(a traceback, a hang, a message naming no variable, or a truncated file read silently).
The v5 files are assembled here byte by byte from the MAT-file format specification
(MathWorks, "MAT-File Format", R2023b: 128-byte header, 8-byte tags, miMATRIX subelements),
and the builder is checked against scipy's own reader on a valid file.
"""

import re
import struct
import subprocess
import sys
import zlib

import h5py
import numpy as np
import pytest
import scipy.io

from ftcal.core.limits import MAX_DECLARED_ELEMENTS
from ftcal.data.logs import read_recording
from ftcal.runtime.errors import FtcalError
from test_logs_mat import logger_tree, signals, write_v5, write_v73  # noqa: F401 (signals: a fixture)

ROOT = "/robot_logger_device"
TREE = {"FTs": {"s": {"data": np.zeros((5, 6)), "timestamps": np.arange(5.0)}}}


def _v73_with(tmp_path, name, mutate):
    path = write_v73(tmp_path / f"{name}.mat", TREE)
    with h5py.File(path, "r+") as fh:
        mutate(fh)
    return path


def _soft_self(fh):
    fh[f"{ROOT}/FTs"]["x"] = h5py.SoftLink(f"{ROOT}/FTs/x")


def _soft_cycle(fh):
    fh[f"{ROOT}/FTs"]["x"] = h5py.SoftLink(f"{ROOT}/FTs/y")
    fh[f"{ROOT}/FTs"]["y"] = h5py.SoftLink(f"{ROOT}/FTs/x")


def _soft_to_root(fh):
    fh[f"{ROOT}/FTs"]["x"] = h5py.SoftLink(ROOT)


def _hard_self(fh):
    group = fh[f"{ROOT}/FTs"]
    group["x"] = group  # the group contains itself


def _reference_loop(fh):
    # A MATLAB cell (object references into #refs#) whose element is the cell itself.
    cell = fh["#refs#"].create_dataset("loop", shape=(1, 1), dtype=h5py.ref_dtype)
    cell[0, 0] = cell.ref
    cell.attrs["MATLAB_class"] = np.bytes_("cell")
    fh[ROOT]["description_list"] = cell
    fh[ROOT]["joints_state"] = fh[f"{ROOT}/FTs"]


def _external(fh):
    del fh[f"{ROOT}/FTs/s/data"]
    fh[f"{ROOT}/FTs/s"]["x"] = h5py.ExternalLink("/dev/zero", "/data")


@pytest.mark.parametrize("mutate, link, message", [
    (_soft_self, f"{ROOT}/FTs/x", "soft link .* never resolves"),
    (_soft_cycle, f"{ROOT}/FTs/x", "soft link .* never resolves"),
    (_soft_to_root, f"{ROOT}/FTs/x", f"links back to {ROOT},"),
    (_hard_self, f"{ROOT}/FTs/x", f"links back to {ROOT}/FTs,"),
    (_reference_loop, f"{ROOT}/description_list{{1}}", f"links back to {ROOT}/description_list,"),
    (_external, f"{ROOT}/FTs/s/x", "link to another file \\(/dev/zero\\)"),
])
def test_hdf5_link_loops_refused_naming_the_link(tmp_path, mutate, link, message):
    """Class: link loops and links out of an HDF5 (.mat v7.3) file: one line naming the file and the link."""
    path = _v73_with(tmp_path, mutate.__name__, mutate)
    with pytest.raises(FtcalError) as info:
        read_recording(path)
    text = str(info.value)
    assert str(path) in text and "\n" not in text
    assert text.split(": ")[1].startswith(link + " ")  # the link itself, not a path 32 levels deep
    assert re.search(message, text)


def test_hdf5_shared_links_read_once(tmp_path):
    """Class: links shared along many paths (no loop). 24 groups, each linking twice to the next, are
    2^24 paths but 24 objects: the read must take one step per object, not per path (main: minutes)."""
    def chain(fh):
        groups = [fh[f"{ROOT}/FTs/s"]] + [fh["#refs#"].create_group(f"g{i}") for i in range(24)]
        for upper, lower in zip(groups[:-1], groups[1:]):
            upper["a"], upper["b"] = lower, lower
    path = _v73_with(tmp_path, "chain", chain)
    code = ("import sys; from ftcal.data.logs import read_recording; from ftcal.runtime.errors import FtcalError\n"
            "try: read_recording(sys.argv[1])\nexcept FtcalError as e: print(e)")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stderr == ""
    assert out.stdout.count("\n") <= 1


# --- MATLAB v5, assembled from the format specification ---

def _element(kind, data):
    return struct.pack("<II", kind, len(data)) + data + bytes(-len(data) % 8)


def _matrix(name, dims, mx_class, body=b""):
    inner = (_element(6, struct.pack("<II", mx_class, 0)) + _element(5, struct.pack(f"<{len(dims)}i", *dims))
             + _element(1, name.encode()) + body)
    return struct.pack("<II", 14, len(inner)) + inner


def _struct(name, dims, fields, children):
    body = (_element(5, struct.pack("<i", 32)) + _element(1, b"".join(f.encode().ljust(32, b"\0") for f in fields))
            + b"".join(children))
    return _matrix(name, dims, 2, body)


def _double(values):
    values = np.asarray(values, float)
    return _matrix("", values.shape, 6, _element(9, values.T.tobytes()))


def _log(data_matrix, compress=False):
    sensor = _struct("", (1, 1), ["data", "timestamps"], [data_matrix, _double(np.arange(5.0)[:, None])])
    variable = _struct("robot_logger_device", (1, 1), ["FTs"], [_struct("", (1, 1), ["s"], [sensor])])
    if compress:
        packed = zlib.compress(variable)
        variable = struct.pack("<II", 15, len(packed)) + packed
    return b"MATLAB 5.0 MAT-file, ftcal test".ljust(116) + bytes(8) + struct.pack("<H", 0x0100) + b"IM" + variable


def test_v5_builder_is_a_mat_file(tmp_path):
    """The hand-assembled bytes are a MAT-file to scipy and to ftcal (so the hostile ones below differ only
    in what they declare)."""
    ft = np.arange(30.0).reshape(5, 6)
    for compress in (False, True):
        path = tmp_path / f"ok{compress}.mat"
        path.write_bytes(_log(_double(ft), compress))
        ours = scipy.io.loadmat(path, simplify_cells=True)["robot_logger_device"]["FTs"]["s"]["data"]
        np.testing.assert_array_equal(ours, ft)
        np.testing.assert_array_equal(read_recording(path).ft["s"].data, ft)


@pytest.mark.parametrize("compress", [False, True])
@pytest.mark.parametrize("data, declared", [
    (_matrix("", (10**6, 10**6), 6, _element(9, bytes(8))), "1,000,000,000,000 values"),  # a 10^12 double
    (_struct("", (10**5, 10**5), ["a"], []), "10,000,000,000 values"),  # a struct array scipy would allocate
    (_matrix("", (10**5, 10**5), 1), "10,000,000,000 values"),  # a cell array
    (_matrix("", (5, 6), 6, struct.pack("<II", 9, 2**32 - 8)), "4,294,967,288 bytes"),  # more bytes than the file
], ids=["double-1e12", "struct-1e10", "cell-1e10", "bytes-4e9"])
def test_v5_declared_sizes_refused_naming_the_variable(tmp_path, data, declared, compress):
    """Class: a v5 file declaring more than it holds or than the limit: refused before scipy allocates,
    naming the file and the variable (main: scipy's MemoryError or reshape error, no variable named)."""
    path = tmp_path / "huge.mat"
    path.write_bytes(_log(data, compress))
    with pytest.raises(FtcalError) as info:
        read_recording(path)
    text = str(info.value)
    assert f"{path}:" in text and "robot_logger_device.FTs.s.data declares " + declared in text
    if "values" in declared:
        assert f"limit of {MAX_DECLARED_ELEMENTS:,}" in text


def test_v5_truncation_always_refused(tmp_path, signals):
    """Class: truncated v5 files. Every cut is refused in one line (main read three cuts silently)."""
    path = write_v5(tmp_path / "full.mat", logger_tree(signals["ft"], signals["temp"], signals["q"],
                                                       signals["t_ft"], signals["t_q"]))
    data = path.read_bytes()
    cut = tmp_path / "cut.mat"
    for n in [*range(0, len(data) - 16, 13), *range(len(data) - 16, len(data))]:
        cut.write_bytes(data[:n])
        with pytest.raises(FtcalError) as info:
            read_recording(cut)
        assert str(cut) in str(info.value) and "\n" not in str(info.value)


# --- Parquet from other writers: no page checksums, only the footer's statistics ---

def _third_party_parquet(path, compression="none"):
    """A table as another tool writes it: statistics in the footer, no page checksums, 3 row groups."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    rng = np.random.default_rng(3)
    n = 900
    columns = {c: rng.normal(0.0, 10.0, n) for c in ("u1", "u2", "u3", "u4", "u5", "u6")}
    columns.update({c: rng.normal(0.0, 1.0, n) for c in ("fx", "fy", "fz", "tx", "ty", "tz")})
    columns["u3"][[5, 400]] = [np.nan, -0.0]  # NaN is not in the statistics, -0.0 equals 0.0
    table = pa.table({**columns, "case": pa.array([f"c{i // 100}" for i in range(n)]),
                      "count": pa.array(np.arange(n) % 7, pa.int32()),
                      "note": pa.array([None if i % 5 else "x" for i in range(n)])})
    pq.write_table(table, path, compression=compression, row_group_size=300, write_page_checksum=False)
    return table


def _read_both(path):
    from ftcal.data.table_chunks import iter_table_chunks
    from ftcal.data.tables import read_arrow

    names = ("u1", "u2", "u4", "u5", "u6"), ("fx", "fy", "fz", "tx", "ty", "tz")
    return read_arrow(path), [chunk for chunk in iter_table_chunks(path, *names, chunk_rows=250)]


@pytest.mark.parametrize("compression", ["none", "snappy"])
def test_parquet_statistics_accept_valid_files(tmp_path, compression):
    """No false alarm: NaN, -0.0, empty cells, integers, strings, row groups that do not align with chunks."""
    path = tmp_path / "ok.parquet"
    table = _third_party_parquet(path, compression)
    whole, chunks = _read_both(path)
    assert whole.schema.equals(table.schema) and whole.num_rows == table.num_rows
    for name in table.column_names:  # array_equal: NaN equals NaN (Table.equals would say the tables differ)
        np.testing.assert_array_equal(np.array(whole.column(name).to_pylist()),
                                      np.array(table.column(name).to_pylist()))
    outputs = ("fx", "fy", "fz", "tx", "ty", "tz")
    np.testing.assert_array_equal(np.vstack([c.outputs for c in chunks]),
                                  np.column_stack([table.column(c).to_numpy() for c in outputs]))


@pytest.mark.parametrize("where, bit", [
    (417, 62),  # the exponent's top bit: the value leaves [min, max]
    ("max", 0),  # the lowest mantissa bit of the row group's largest value: the extreme itself moves
])
def test_parquet_bit_flip_without_checksums_refused(tmp_path, where, bit):
    """Class: a flipped bit in a Parquet data page of a file without page checksums (main: read silently).

    The value's 8 bytes are found in the uncompressed PLAIN page by their own bit pattern, flipped,
    and the file is read by both readers: each refuses it in one line naming file, column and row group."""
    path = tmp_path / "third-party.parquet"
    table = _third_party_parquet(path)
    fz = table.column("fz").to_numpy()
    row = int(np.argmax(fz[300:600])) + 300 if where == "max" else where  # row group 1 holds rows 300-599
    data = bytearray(path.read_bytes())
    pair = fz[row - 1:row + 1].tobytes()  # with its neighbour: the footer and page header hold the max alone
    assert bytes(data).count(pair) == 1
    data[bytes(data).index(pair) + 8 + bit // 8] ^= 1 << (bit % 8)
    path.write_bytes(data)
    for read in (lambda: _read_both(path)[0], lambda: _read_both(path)[1]):
        with pytest.raises(FtcalError) as info:
            read()
        text = str(info.value)
        assert text.startswith(f"{path}: column 'fz', row group 1:") and "\n" not in text
        assert "ftcal dataset" in text  # the advice: files ftcal writes carry checksums


def test_parquet_undecodable_chunk_named(tmp_path):
    """Class: a page pyarrow cannot decode (snappy data cut short): the line names column and row group
    (main named neither)."""
    import pyarrow.parquet as pq

    path = tmp_path / "third-party.parquet"
    _third_party_parquet(path, "snappy")
    meta = pq.read_metadata(path)
    chunk = meta.row_group(1).column([meta.schema.column(i).path for i in range(meta.num_columns)].index("fz"))
    start = chunk.dictionary_page_offset if chunk.has_dictionary_page else chunk.data_page_offset
    end = start + chunk.total_compressed_size
    data = bytearray(path.read_bytes())
    data[end - chunk.total_compressed_size // 20:end] = b"\xff" * (chunk.total_compressed_size // 20)
    path.write_bytes(data)
    for read in (lambda: _read_both(path)[0], lambda: _read_both(path)[1]):
        with pytest.raises(FtcalError, match=f"^{re.escape(str(path))}: column 'fz', row group 1 cannot be read"):
            read()


def _dims_in_small_element(matrix: bytes) -> bytes:
    """The dimensions subelement (bytes 24..40 of a matrix) turned into a 2-byte small element: no dimensions."""
    return matrix[:24] + struct.pack("<HH", 5, 2) + bytes(4) + matrix[40:]


@pytest.mark.parametrize("data", [
    _matrix("", (5, 6), 6, struct.pack("<II", 11, 240) + bytes(240)),  # data of element type 11 (none such)
    _dims_in_small_element(_double(np.zeros((5, 6)))),  # an array without dimensions
    _matrix("", (5, 6), 6),  # an array without data: scipy reads the next array as its data
], ids=["type-11", "no-dimensions", "no-data"])
def test_v5_structures_that_crash_scipy_refused(tmp_path, data):
    """Class: a v5 file whose structure makes scipy's compiled reader crash the interpreter (segmentation
    fault on main; each found by flipping one bit of a logger file). Run in a child process: on main it dies."""
    path = tmp_path / "crash.mat"
    path.write_bytes(_log(data))
    code = ("import sys; from ftcal.data.logs import read_recording; from ftcal.runtime.errors import FtcalError\n"
            "try: read_recording(sys.argv[1])\nexcept FtcalError as e: print(e)")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.returncode
    assert out.stdout.startswith(f"Recording {path}: robot_logger_device.FTs.s.data") and out.stdout.count("\n") == 1


def test_c_range_check_has_no_infinite_literal():
    """Found by the adversarial pass (a model whose range bound is null, read as -inf): the slack of an open
    side is infinite, so the other side's bound was printed as 'inf', which is no C. An infinite bound
    checks nothing (as predict's own check), so it is left out."""
    from types import SimpleNamespace

    from ftcal.core.ranges import RANGE_TOLERANCE
    from ftcal.files.c_code import _in_range

    text = _in_range(SimpleNamespace(input_range_=np.array([[-np.inf, 1.0], [0.0, 2.0]])), "cal",
                     SimpleNamespace(real="double"))
    assert "inf" not in text and "u[0]" not in text
    slack = RANGE_TOLERANCE * 2.0  # range 0..2: slack is the tolerance times max(width, 1)
    bounds = re.search(r"u\[1\] >= (\S+) && u\[1\] <= (\S+)\)\)", text).groups()
    assert [float(b) for b in bounds] == [-slack, 2.0 + slack]
