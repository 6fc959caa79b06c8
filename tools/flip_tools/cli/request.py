"""flip request: RequestFlip on a running graph (its ROS_DOMAIN_ID); prints the response (exit 4:
rejected)."""
from __future__ import annotations

import argparse
import json
import os
import sys

from flip_tools.flip_request import request_distance
from flip_tools.rosenv import set_process_ros_env

from .common import EXIT_INFRA, EXIT_INTERRUPTED, EXIT_OK, EXIT_REJECTED, KINDS
from .options import scenario_opts
from .services import call_request_flip, response_dict


def add_parser(sub) -> None:
    sp = sub.add_parser("request", help="RequestFlip on a running graph; prints the response")
    sp.add_argument("kind", choices=list(KINDS))
    # the request carries kind, apex, distance and platform; the robot is the running graph's
    scenario_opts(sp, plan=True, flight_check=False, robot=False)
    sp.add_argument("--kind-id", type=int, help=argparse.SUPPRESS)
    sp.add_argument("--domain", type=int, help="default: $ROS_DOMAIN_ID")
    sp.add_argument("--timeout", type=float, default=120.0)
    sp.set_defaults(func=cmd_request)


def cmd_request(args) -> int:
    from flip_tools.launcher import GraphWatcher
    set_process_ros_env()
    dom = args.domain if args.domain is not None else int(os.environ.get("ROS_DOMAIN_ID", "0"))
    watcher = GraphWatcher(domain_id=dom, name="flip_request")
    try:
        kind = args.kind_id if args.kind_id is not None else KINDS[args.kind]
        r = call_request_flip(watcher, kind, args.apex or 0.0, request_distance(args),
                              args.platform or 0.0, timeout=args.timeout)
    except TimeoutError as e:
        print(str(e), file=sys.stderr)
        return EXIT_INFRA
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    finally:
        watcher.close()
    print(json.dumps(response_dict(r), indent=2))
    return EXIT_OK if r.accepted else EXIT_REJECTED
