"""How many single-bit flips in a third-party Parquet file (no page checksums) ftcal detects.

``PYTHONPATH=src:. python -m benchmarks.parquet_bitflips [--flips 500] [--seed 17]``

A calibration-like table (8 strain channels, 6 wrench columns, 20,000 rows in 4 row
groups, with footer statistics as every common writer adds them) is written by pyarrow
without page checksums: uncompressed and snappy with pyarrow's default dictionary
encoding (distinct values go to a dictionary page, rows are run-length-coded indices
into it), and uncompressed plain. Each trial flips one random bit in the bytes of the
column chunks (page headers, dictionary and data pages, not the footer) and reads the
file with ``ftcal.data.tables.read_arrow`` (the whole-table reader) and
``ftcal.data.table_chunks.iter_table_chunks`` (the streamed one). Each read is:
detected (a one-line FtcalError), unchanged (read, values identical: the bit was
unused), or silently changed (read, some value differs; also counted: those where the
change exceeds 10⁻⁶ of the column's range, i.e. could matter to a calibration whose
sensor noise is ~10⁻⁴ of range). Any other exception is counted as a crash. Run it
with ``PYTHONPATH`` pointing at the tree to measure.
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from benchmarks.load_cases import make_load_cases

INPUTS = tuple(f"u{i}" for i in range(1, 9))
OUTPUTS = ("fx", "fy", "fz", "tx", "ty", "tz")


def _table(n: int = 20_000) -> pa.Table:
    counts, wrench, _ = make_load_cases(n, n_groups=20, n_channels=8, seed=3)
    return pa.table({**{c: counts[:, i] for i, c in enumerate(INPUTS)},
                     **{c: wrench[:, i] for i, c in enumerate(OUTPUTS)}})


def _chunk_spans(path: Path) -> list[tuple[int, int]]:
    meta = pq.read_metadata(path)
    spans = []
    for g in range(meta.num_row_groups):
        for c in range(meta.num_columns):
            col = meta.row_group(g).column(c)
            start = col.dictionary_page_offset if col.has_dictionary_page else col.data_page_offset
            spans.append((start, start + col.total_compressed_size))
    return spans


def _read(path: Path, reader: str) -> np.ndarray:
    from ftcal.data.table_chunks import iter_table_chunks
    from ftcal.data.tables import read_arrow

    if reader == "whole":
        table = read_arrow(path)
        return np.column_stack([table.column(c).to_numpy(zero_copy_only=False) for c in (*INPUTS, *OUTPUTS)])
    return np.vstack([np.hstack([chunk.inputs, chunk.outputs])
                      for chunk in iter_table_chunks(path, INPUTS, OUTPUTS, chunk_rows=3000)])


def measure(flips: int, seed: int) -> dict[tuple[str, str], Counter]:
    from ftcal.runtime.errors import FtcalError

    rng = random.Random(seed)
    table = _table()
    truth = np.column_stack([table.column(c).to_numpy() for c in (*INPUTS, *OUTPUTS)])
    results: dict[tuple[str, str], Counter] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for codec, dictionary in (("none", True), ("snappy", True), ("none", False)):
            clean = Path(tmp) / f"clean-{codec}.parquet"
            pq.write_table(table, clean, compression=codec, use_dictionary=dictionary, row_group_size=5000,
                           write_page_checksum=False)
            codec = f"{codec}, {'dictionary' if dictionary else 'plain'}"
            data = clean.read_bytes()
            spans = _chunk_spans(clean)
            total = sum(b - a for a, b in spans)
            bad = Path(tmp) / f"flip-{codec}.parquet"
            for _ in range(flips):
                k = rng.randrange(total * 8)
                for a, b in spans:
                    if k < (b - a) * 8:
                        byte = a + k // 8
                        break
                    k -= (b - a) * 8
                corrupt = bytearray(data)
                corrupt[byte] ^= 1 << (k % 8)
                bad.write_bytes(corrupt)
                for reader in ("whole", "chunks"):
                    tally = results.setdefault((codec, reader), Counter())
                    try:
                        got = _read(bad, reader)
                    except FtcalError as exc:
                        tally["detected"] += 1
                        assert "\n" not in str(exc)
                    except Exception:  # noqa: BLE001 - what the measurement counts
                        tally["crash"] += 1
                    else:
                        same = got.shape == truth.shape and np.array_equal(got, truth, equal_nan=True)
                        tally["unchanged" if same else "silently changed"] += 1
                        if not same and got.shape == truth.shape:
                            # how much it matters: the largest change, relative to its column's range
                            change = np.nanmax(np.abs(got - truth) / np.ptp(truth, axis=0), initial=0.0)
                            tally["changed > 1e-6 of range"] += bool(not change <= 1e-6)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flips", type=int, default=500)
    parser.add_argument("--seed", type=int, default=17)
    args = parser.parse_args()
    print("| compression | reader | flips | detected | unchanged | silently changed | of which > 1e-6 of range "
          "| crash |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for (codec, reader), tally in measure(args.flips, args.seed).items():
        n = sum(tally[k] for k in ("detected", "unchanged", "silently changed", "crash"))
        print(f"| {codec} | {reader} | {n} | {tally['detected']} ({100 * tally['detected'] / n:.1f} %) | "
              f"{tally['unchanged']} | {tally['silently changed']} ({100 * tally['silently changed'] / n:.1f} %) | "
              f"{tally['changed > 1e-6 of range']} | {tally['crash']} |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
