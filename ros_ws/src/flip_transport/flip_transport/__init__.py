"""flip_transport: the lockstep message transport shared by the graph's nodes (simulator, planner, controller).

:mod:`cdr` (serialized messages read as numpy views, no ROS), :mod:`lockstep` (QoS, wait sets over
subscriptions, serialized templates, CPU pinning), :mod:`node_stop` (how a node process ends) and
``_rcl_io`` (the per-step messages on rcl's C API, native/rcl_io.cpp).
"""
