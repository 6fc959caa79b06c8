"""How a node process of the graph ends: its loop runs until it returns or a stop (SIGINT/SIGTERM)
arrives, then the node is closed and the process exits 0.

A SIGINT reaches an rclpy node twice: rclpy's handler wakes the node's wait set (its
SignalHandlerGuardCondition) or its spin (ExternalShutdownException), and Python raises
KeyboardInterrupt at whatever bytecode runs next. Usually the KeyboardInterrupt lands inside the
loop. When the wake wins the race, it lands later: in the clean-up, or in ``sys.exit`` itself, and
the process dies by SIGINT (exit code -2) after a clean run. CI saw that once in the controller
node (``test_hop_lands_through_the_graph``: tsc -2). So the end of the loop is the stop: from
there on, SIGINT is ignored.
"""
from __future__ import annotations

import signal
from typing import Callable

from rclpy.executors import ExternalShutdownException


def run_until_stopped(loop: Callable[[], int | None], close: Callable[[], None]) -> int:
    """``loop()`` until it returns (its code, None = 0) or a stop ends it (0); then ``close()``.

    SIGINT is ignored from the moment the loop ends, so a KeyboardInterrupt already on its way
    cannot cut ``close()`` short or turn the exit code into -2. One that lands in the few bytecodes
    before that takes effect skips ``close()`` (the process is ending anyway) and still gives 0."""
    rc = 0
    try:
        try:
            rc = loop() or 0
        except (KeyboardInterrupt, ExternalShutdownException):
            rc = 0
        finally:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            close()
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return rc
