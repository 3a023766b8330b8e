"""Peers of the Zenoh latency benchmark, each its own process (as on a robot): ``python -m benchmarks.zenoh_peers``.

* ``publish ENDPOINT RATE SECONDS [RT_PRIORITY]``: the robot's driver. Publishes CDR WrenchStamped on ``ft/raw`` at RATE Hz,
  each stamped with CLOCK_MONOTONIC at the moment of sending (``time.monotonic_ns``: one clock for every
  process on this host), so the receiver reads the latency from the message it gets back.
* ``relay ENDPOINT``: Zenoh and a Python callback without ftcal: republishes every ``ft/raw`` payload unchanged on
  ``ft/compensated`` (the floor under ``ftcal live --zenoh``'s own work).

Both use the node's publisher settings (:func:`ftcal.live.zenoh_node.publisher_settings`) and a peer
configuration with multicast scouting off and explicit tcp/127.0.0.1 endpoints.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def publish(endpoint: str, rate: float, seconds: float, rt_priority: int = 0) -> None:
    import os

    import zenoh

    from ftcal.live.cdr import encode_stamped
    from ftcal.live.zenoh_node import publisher_settings, zenoh_config

    if rt_priority:  # as a real-time driver would run; Zenoh's threads inherit it
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(rt_priority))
    session = zenoh.open(zenoh_config(connect=(endpoint,)))
    pub = session.declare_publisher("ft/raw", **publisher_settings())
    time.sleep(1.0)  # routes established
    rng = np.random.default_rng(0)
    noise = rng.normal(scale=0.05, size=(int(rate * seconds), 6)).tolist()
    start = time.monotonic()
    for k, row in enumerate(noise):
        pub.put(encode_stamped(time.monotonic_ns(), "ft", [row[0], row[1], row[2] - 11.8, row[3], row[4], row[5]]))
        ahead = (k + 1) / rate - (time.monotonic() - start)
        if ahead > 0:
            time.sleep(ahead)
    time.sleep(0.5)
    session.close()


def relay(endpoint: str) -> None:
    import signal
    import threading

    import zenoh

    from ftcal.live.zenoh_node import publisher_settings, zenoh_config

    session = zenoh.open(zenoh_config(listen=(endpoint,)))
    pub = session.declare_publisher("ft/compensated", **publisher_settings())
    sub = session.declare_subscriber("ft/raw", lambda sample: pub.put(sample.payload))
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    print("relay ready", flush=True)
    done.wait()
    sub.undeclare()
    session.close()


if __name__ == "__main__":
    if sys.argv[1] == "publish":
        publish(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]) if len(sys.argv) > 5 else 0)
    else:
        relay(sys.argv[2])
