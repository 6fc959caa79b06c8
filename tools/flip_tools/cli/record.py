"""flip record: topics to DIR/bag (rosbag2, MCAP) until SIGINT or --duration; also the recorder flip
starts for its runs (--bag, --stats)."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from flip_tools.rosenv import set_process_ros_env

from .common import EXIT_OK


def add_parser(sub) -> None:
    sp = sub.add_parser("record", help="record topics to DIR/bag (rosbag2, MCAP) until SIGINT or --duration")
    sp.add_argument("topics", nargs="*", help="topics (default: every topic that appears)")
    sp.add_argument("--out", help="output dir; the bag is DIR/bag")
    sp.add_argument("--bag", help=argparse.SUPPRESS)
    sp.add_argument("--stats", help=argparse.SUPPRESS)
    sp.add_argument("--all", action="store_true", help="also every other topic that appears")
    sp.add_argument("--duration", type=float, help="wall seconds")
    sp.add_argument("--domain", type=int, help="default: $ROS_DOMAIN_ID")
    sp.set_defaults(func=cmd_record)


def cmd_record(args) -> int:
    from flip_tools.recorder import record
    set_process_ros_env()
    if args.bag:
        bag = Path(args.bag)
    elif args.out:
        bag = Path(args.out) / "bag"
    else:
        raise SystemExit("flip record: give --out DIR (bag goes to DIR/bag)")
    dom = args.domain if args.domain is not None else (int(os.environ["ROS_DOMAIN_ID"])
                                                        if os.environ.get("ROS_DOMAIN_ID") else None)
    record(bag, topics=args.topics, all_topics=args.all or not args.topics, duration=args.duration,
           domain_id=dom, stats_path=args.stats)
    return EXIT_OK
