#!/usr/bin/env python3
"""tsc_node with a zero-cost tick, for `scripts/bench_graph.py --zero-tick`: the controller node as it
is (its transport, the state read from the serialized messages, the command published), but
``Controller.compute`` answers every state with zero torques at once.  A graph with it runs at the
real-time factor the real graph would reach with an instant controller (the robot, without torques,
sinks to the ground: a conservative ceiling, the simulator then has more contacts to step)."""
import sys

import numpy as np
from tsc_controller import domains, tsc_node
from tsc_controller.dynamics import MOTOR_NAMES


def main():
    zeros = np.zeros(len(MOTOR_NAMES))
    domains.Controller.compute = lambda self, q, v, t, details=True: (zeros, {})
    return tsc_node.main()


if __name__ == "__main__":
    sys.exit(main())
