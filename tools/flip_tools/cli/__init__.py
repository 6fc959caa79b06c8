"""flip — the somersault command-line tool (stand-in for ros2 launch / service call / bag record).

  flip run {backflip|frontflip} [--distance M] [--apex M] [--platform M] [--ground-offset M]
           [--flywheel I|II|III] [--motor-speed-scale X] [--flywheel-torque NM]
           [--controller JSON] [--out DIR] [--video] [--duration S]
  flip sim --duration S --out DIR          simulator alone, zero torques, recorded
  flip stand --duration S --out DIR        simulator + controller holding the standing pose
                                           ([--io rcl|python]: per-step messages through rcl's C API
                                           or rclpy, for both nodes)
  flip plan {backflip|frontflip|hop} [...] --out DIR    FSLIP optimisation alone, no ROS
  flip request {backflip|frontflip|hop} [...]           RequestFlip on a running graph
  flip record [TOPIC ...] --out DIR [--duration S]      rosbag2 (MCAP) until SIGINT/duration
  flip summarize DIR                       (re)compute summary.json + plots from DIR/bag
  flip study flywheel [--simulate]         paper's Table I: flip C with flywheels I, II, III
  flip sweep [--flips A B C D] (--grid KNOB=V1,V2,... | --random N --range KNOB=LO:HI ...)
             [--set KNOB=V] [--seed S] [--workers N] [--address HOST:PORT] --out DIR
                                           landing rate over perturbations of the simulated robot
                                           (flip_tools.perturb knobs), offline flips as Ray tasks

One module per subcommand (its `add_parser` and `cmd_*`); `main` builds the parser from them.

run, sim and stand hold /dev/cpu_dma_latency at 0 us while the graph runs, where they may
(--cpu-dma-latency US|off; flip_tools.cpu_latency); run.json says whether it was held. The
simulator and controller share one CPU, as SCHED_BATCH threads in lockstep (--lockstep-sched
batch|other; flip_transport.lockstep); run.json's lockstep_sched says which. The simulator's
routine lockstep steps run in C++ (--sim-loop python: every step in Python; the same messages).
The simulator publishes each foot's contact wrench at 200 Hz of sim time (--wrench-rate HZ, 0: off).

Exit codes: 0 ok (run: the robot landed, per the bag), 1 ran but did not land, 2 usage or
argument error (nothing started or written), 3 infrastructure failure (a node or the recorder died,
graph not ready, timeout), 4 request rejected / infeasible, 130 interrupted.
"""
