"""``ftcal topics``: the topics of a ROS bag, with message type, count and rate."""

from __future__ import annotations

import argparse

from ._examples import epilog


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "topics", **epilog("topics"), help="list a ROS bag's topics (type, count, rate)",
        description="List the topics of a ROS 1 .bag, a ROS 2 bag folder, a .db3 or an .mcap file: message "
                    "type, message count and mean rate (Hz, from the bag's receive times). Use the names with "
                    "'ftcal dataset BAG --wrench-topic ...'.")
    parser.add_argument("bag", metavar="BAG", help="ROS 1 .bag, ROS 2 bag folder, .db3 or .mcap")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..data.bags import list_topics
    from ._common import single_line

    summaries = list_topics(args.bag)
    rows = [("topic", "type", "count", "rate [Hz]")]
    rows += [(single_line(s.name), single_line(s.msgtype), str(s.count), "-" if s.rate is None else f"{s.rate:.6g}")
             for s in summaries]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    print(f"{single_line(args.bag)}: {len(summaries)} topic(s)")
    for r in rows:
        print("  " + "  ".join([r[0].ljust(widths[0]), r[1].ljust(widths[1]), r[2].rjust(widths[2]),
                                r[3].rjust(widths[3])]).rstrip())
    return 0
