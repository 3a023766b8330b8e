"""Nodes of the Zenoh latency benchmark other than ``ftcal live --zenoh``, each its own process (as a node is):
``python -m benchmarks.zenoh_peers relay|node ENDPOINT [lowlatency]``.

* ``relay``: Zenoh and a Python callback without ftcal: republishes every ``ft/raw`` payload unchanged on
  ``ft/compensated`` (the floor under ``ftcal live --zenoh``'s own work).
* ``node``: what ``ftcal live --zenoh --listen ENDPOINT --noise-std 0.05,0.004`` runs, from Python.

Both use the node's publisher settings (:func:`ftcal.live.zenoh_node.publisher_settings`) and peer configuration
(:func:`ftcal.live.zenoh_node.zenoh_config`: multicast scouting off, explicit tcp/127.0.0.1 endpoints, the
queued transport, or with ``lowlatency`` Zenoh's low-latency one, to measure the difference). The publishing and
measuring side is :func:`benchmarks.bench_live.live_zenoh` itself.
"""

from __future__ import annotations

import sys


def relay(endpoint: str, low_latency: bool = False) -> None:
    import signal
    import threading

    import zenoh

    from ftcal.live.zenoh_node import publisher_settings, zenoh_config

    session = zenoh.open(zenoh_config(listen=(endpoint,), low_latency=low_latency))
    pub = session.declare_publisher("ft/compensated", **publisher_settings())
    sub = session.declare_subscriber("ft/raw", lambda sample: pub.put(sample.payload))
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    print("relay ready", flush=True)
    done.wait()
    sub.undeclare()
    session.close()


def node(endpoint: str, low_latency: bool = False) -> None:
    import signal

    from ftcal.live import LiveCalibrator
    from ftcal.live.zenoh_node import ZenohOptions, serve

    def stop(*_):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)  # as ftcal live: the node's loop ends, the session closes
    try:
        serve(LiveCalibrator(noise_std=[0.05] * 3 + [0.004] * 3),
              ZenohOptions(listen=(endpoint,), low_latency=low_latency))
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    if sys.argv[1:2] not in (["relay"], ["node"]) or len(sys.argv) not in (3, 4) or sys.argv[3:] not in ([], ["lowlatency"]):
        sys.exit("usage: python -m benchmarks.zenoh_peers relay|node ENDPOINT [lowlatency]")
    (relay if sys.argv[1] == "relay" else node)(sys.argv[2], low_latency=sys.argv[3:] == ["lowlatency"])
