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
    from ..workflow.datasets import bag_topics

    print(bag_topics(args.bag).summary())
    return 0
