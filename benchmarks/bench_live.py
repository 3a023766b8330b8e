"""The live calibrator: replay speed (blocks against one sample at a time), memory over a long replay, Zenoh latency.

* ``live_replay``: :meth:`LiveCalibrator.run` over a simulated 500 Hz recording (drift, moves, a
  contact, a tool), in blocks of 65,536 samples; ``live_steps``: the same calibrator one
  :meth:`~LiveCalibrator.step` at a time (the per-sample Python path a live loop uses).
* ``live_table_prepare`` writes a long 1 kHz Parquet recording chunk by chunk (not timed);
  ``live_table_replay`` runs ``ftcal live --replay`` on it in-process: peak memory for 6 minutes
  and for 1 hour of data says whether memory stays flat.
* ``live_zenoh``: ``ftcal live --zenoh`` in a child process, a peer in this one publishing CDR
  WrenchStamped at ``rate`` Hz over tcp/127.0.0.1 for ``seconds``; latency is publish → the
  compensated wrench back in this process (round trip through two peers), per message.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np


def _recording(n: int, rate: float = 500.0):
    from ftcal.sim.live_scenario import LiveScenario, simulate_live

    return simulate_live(LiveScenario(duration=n / rate, rate=rate, contacts=((30.5, 5.0, 10.0),), seed=1))


def _calibrator(rec_tools):
    from ftcal.live import LiveCalibrator
    from ftcal.payload.parameters import PayloadParameters

    tool = rec_tools["gripper"]
    payload = PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                                fit={"residual_rms": np.r_[np.full(3, 0.05), np.full(3, 0.004)]})
    return LiveCalibrator(tools={"gripper": payload}, tool="gripper", walk_std=[3, 3, 3, .3, .3, .3])


def live_replay(n: int, block: int = 65_536) -> dict:
    from ftcal.sim.live_scenario import LiveScenario

    rec = _recording(n)
    live = _calibrator(LiveScenario().tools)
    live.run(rec.time[:10], wrench=rec.wrench[:10], quaternion=rec.quaternion[:10])  # imports, first call
    start, cpu = time.perf_counter(), time.process_time()
    for a in range(10, n, block):
        live.run(rec.time[a:a + block], wrench=rec.wrench[a:a + block], quaternion=rec.quaternion[a:a + block])
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return {"seconds": seconds, "cpu_seconds": cpu, "samples": n - 10, "samples_per_s": (n - 10) / seconds,
            "samples_per_cpu_s": (n - 10) / cpu}


def live_steps(n: int) -> dict:
    from ftcal.sim.live_scenario import LiveScenario

    rec = _recording(n)
    live = _calibrator(LiveScenario().tools)
    live.step(rec.time[0], wrench=rec.wrench[0], quaternion=rec.quaternion[0])
    start, cpu = time.perf_counter(), time.process_time()
    for k in range(1, n):
        live.step(rec.time[k], wrench=rec.wrench[k], quaternion=rec.quaternion[k])
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return {"seconds": seconds, "cpu_seconds": cpu, "samples": n - 1, "samples_per_s": (n - 1) / seconds,
            "samples_per_cpu_s": (n - 1) / cpu, "us_per_step": 1e6 * cpu / (n - 1)}


def table_path(minutes: float) -> Path:
    return Path(tempfile.gettempdir()) / "ftcal-bench-live" / f"live-{minutes:g}min.parquet"


def live_table_prepare(minutes: float) -> dict:
    """A 1 kHz recording of ``minutes`` written in one-minute pieces: a still sensor, a walking bias, noise."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = table_path(minutes)
    if path.exists():
        return {"seconds": 0.0}
    path.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    bias = np.zeros(6)
    tmp = path.with_suffix(".partial")
    with pq.ParquetWriter(tmp, pa.schema([(c, pa.float64()) for c in
                                          ("time", "qx", "qy", "qz", "qw", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz")])) as w:
        for minute in range(int(np.ceil(minutes))):
            t = minute * 60.0 + np.arange(60_000) / 1000.0
            walk = bias + np.cumsum(rng.normal(scale=3.0 / 60.0 / np.sqrt(1000.0), size=(t.size, 6)), axis=0)
            bias = walk[-1]
            wrench = walk + rng.normal(scale=0.05, size=(t.size, 6))
            wrench[:, 2] += -1.2 * 9.81
            cols = {"time": t, "qx": np.zeros(t.size), "qy": np.zeros(t.size), "qz": np.zeros(t.size),
                    "qw": np.ones(t.size)}
            cols.update({c: wrench[:, j] for j, c in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))})
            w.write_table(pa.table(cols))
    tmp.rename(path)
    return {"seconds": 0.0}


def live_table_replay(minutes: float) -> dict:
    """``ftcal live --replay`` in this process (no tool: the table's tool is 1.2 kg at the origin, unknown)."""
    from ftcal.cli import main

    out = table_path(minutes).with_name(f"out-{minutes:g}.parquet")
    start, cpu = time.perf_counter(), time.process_time()
    code = main(["live", "--replay", str(table_path(minutes)), "--orientation", "qx,qy,qz,qw",
                 "--wrench", "Fx,Fy,Fz,Tx,Ty,Tz", "--noise-std", "0.05,0.05", "--walk-std", "3,3", "-o", str(out)])
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    out.unlink(missing_ok=True)
    if code != 0:
        raise RuntimeError(f"ftcal live --replay exited {code}")
    return {"seconds": seconds, "cpu_seconds": cpu, "samples": int(minutes * 60_000),
            "samples_per_s": minutes * 60_000 / seconds}


def live_zenoh(rate: float, seconds: float) -> dict:
    """Round-trip latency publish → compensated wrench back, through ``ftcal live --zenoh`` on loopback."""
    import signal
    import socket
    import subprocess
    import sys

    import zenoh

    from ftcal.live.cdr import WRENCH_DOUBLES, decode_stamped
    from ftcal.live.zenoh_node import typestore, wrench_message, zenoh_config

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    node = subprocess.Popen([ftcal, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--noise-std",
                             "0.05,0.004"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    node.stdout.readline()
    store = typestore()
    arrival = {}
    session = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",)))

    def on(sample):  # the stamp only, read with ftcal's codec (tests check it against rosbags)
        arrival[decode_stamped(sample.payload.to_bytes(), WRENCH_DOUBLES).stamp_ns] = time.perf_counter()

    sub = session.declare_subscriber("ft/compensated", on)
    pub = session.declare_publisher("ft/raw")
    time.sleep(1.0)
    rng = np.random.default_rng(0)
    n = int(rate * seconds)
    payloads = [wrench_message(store, 1_000_000_000 + int(k * 1e9 / rate), "ft",
                               np.r_[0.0, 0.0, -11.8, 0.0, 0.0, 0.0] + rng.normal(scale=0.05, size=6))
                for k in range(n)]
    sent = {}
    node_cpu0, cpu0 = _process_cpu(node.pid), time.process_time()
    start = time.perf_counter()
    for k in range(n):
        stamp = 1_000_000_000 + int(k * 1e9 / rate)
        sent[stamp] = time.perf_counter()
        pub.put(payloads[k])
        ahead = (k + 1) / rate - (time.perf_counter() - start)
        if ahead > 0:
            time.sleep(ahead)
    time.sleep(1.0)
    node_cpu, cpu = _process_cpu(node.pid) - node_cpu0, time.process_time() - cpu0
    sub.undeclare()
    session.close()
    node.send_signal(signal.SIGTERM)
    node.communicate(timeout=60)
    latency = np.array([arrival[s] - t for s, t in sent.items() if s in arrival])
    return {"seconds": seconds, "rate": rate, "sent": n, "received": int(latency.size),
            "median_ms": 1e3 * float(np.median(latency)), "p99_ms": 1e3 * float(np.quantile(latency, 0.99)),
            "max_ms": 1e3 * float(latency.max()), "node_cpu_seconds": node_cpu, "peer_cpu_seconds": cpu,
            "node_cpu_us_per_message": 1e6 * node_cpu / n, "load_average": os.getloadavg()[0]}


def _process_cpu(pid: int) -> float:
    """User + system CPU seconds of a process so far (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


LIVE_CASES = {f.__name__: f for f in (live_replay, live_steps, live_table_prepare, live_table_replay, live_zenoh)}


def live_section(run_case, sizes: dict) -> tuple[list[str], str]:
    """Rows of BENCHMARKS.md and the headline."""
    blocks = run_case("live_replay", n=sizes["live_n"])
    steps = run_case("live_steps", n=sizes["live_steps_n"])
    memory = []
    for minutes in sizes["live_minutes"]:
        run_case("live_table_prepare", minutes=minutes)
        memory.append((minutes, run_case("live_table_replay", minutes=minutes)))
    zen = [run_case("live_zenoh", rate=rate, seconds=sizes["live_zenoh_s"]) for rate in (1000.0, 2000.0)]
    out = ["## Live calibrator (`ftcal live`, `ftcal.live.LiveCalibrator`)", "",
           "| case | samples | wall | CPU | samples/s (wall) | samples/CPU s | peak memory |",
           "|---|---:|---:|---:|---:|---:|---:|",
           f"| `run`, blocks of 65,536 (500 Hz recording, moves, a contact) | {blocks['samples']:,} | "
           f"{fmt(blocks['seconds'])} | {fmt(blocks['cpu_seconds'])} | {blocks['samples_per_s']:,.0f} | "
           f"{blocks['samples_per_cpu_s']:,.0f} | {blocks['peak_rss_mb']:,.0f} MB |",
           f"| `step`, one sample at a time | {steps['samples']:,} | {fmt(steps['seconds'])} | "
           f"{fmt(steps['cpu_seconds'])} | {steps['samples_per_s']:,.0f} | {steps['samples_per_cpu_s']:,.0f} | "
           f"{steps['peak_rss_mb']:,.0f} MB |"]
    for minutes, r in memory:
        out.append(f"| `ftcal live --replay`, {minutes:g} min at 1 kHz (Parquet in and out) | {r['samples']:,} | "
                   f"{fmt(r['seconds'])} | {fmt(r['cpu_seconds'])} | {r['samples_per_s']:,.0f} | "
                   f"{r['samples'] / r['cpu_seconds']:,.0f} | {r['peak_rss_mb']:,.0f} MB |")
    ratio = steps["samples_per_cpu_s"] / blocks["samples_per_cpu_s"]
    out += ["", f"`step` runs {ratio:.2f}x the samples per CPU second of `run`'s blocks (the per-sample path is "
            "plain Python floats; blocks are numpy prefix scans).", "",
            "| Zenoh loopback, round trip publish → compensated | sent | received | median | p99 | max | node CPU "
            "| node CPU per message | peer CPU | load average |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in zen:
        out.append(f"| {r['rate']:,.0f} Hz for {r['seconds']:g} s | {r['sent']:,} | {r['received']:,} | "
                   f"{r['median_ms']:.2f} ms | {r['p99_ms']:.2f} ms | {r['max_ms']:.2f} ms | "
                   f"{fmt(r['node_cpu_seconds'])} | {r['node_cpu_us_per_message']:.0f} µs | "
                   f"{fmt(r['peer_cpu_seconds'])} | {r['load_average']:.1f} |")
    out += ["", "The Zenoh figures include the publishing peer, the node and the receiving peer on the same "
            "2 cores (load average: the machine's, at the end); the node handles each message in its "
            "subscriber callback (ftcal.live.cdr, one `step`).", ""]
    headline = (f"replay {blocks['samples_per_cpu_s']:,.0f} samples per CPU second in blocks (target ≥ 200,000/s), "
                f"{steps['samples_per_cpu_s']:,.0f} one step at a time ({ratio:.2f}x; target ≥ 20,000); peak memory {memory[0][1]['peak_rss_mb']:,.0f} "
                f"MB for {memory[0][0]:g} min and {memory[-1][1]['peak_rss_mb']:,.0f} MB for {memory[-1][0]:g} min; "
                f"Zenoh {zen[-1]['rate']:,.0f} Hz: {zen[-1]['received']:,} of {zen[-1]['sent']:,} back, p99 "
                f"{zen[-1]['p99_ms']:.1f} ms (target ≤ 2 ms)")
    return out, headline


def fmt(seconds: float) -> str:
    return f"{seconds:.2f} s"
