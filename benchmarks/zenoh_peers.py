"""The relay of the Zenoh latency benchmark, its own process (as a node is): ``python -m benchmarks.zenoh_peers relay
ENDPOINT``.

Zenoh and a Python callback without ftcal: it republishes every ``ft/raw`` payload unchanged on ``ft/compensated``
(the floor under ``ftcal live --zenoh``'s own work). It uses the node's publisher settings
(:func:`ftcal.live.zenoh_node.publisher_settings`) and peer configuration
(:func:`ftcal.live.zenoh_node.zenoh_config`: multicast scouting off, explicit tcp/127.0.0.1 endpoints, the
low-latency transport). The publishing and measuring side is :func:`benchmarks.bench_live.live_zenoh` itself.
"""

from __future__ import annotations

import sys


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
    if sys.argv[1:2] != ["relay"] or len(sys.argv) != 3:
        sys.exit("usage: python -m benchmarks.zenoh_peers relay ENDPOINT")
    relay(sys.argv[2])
