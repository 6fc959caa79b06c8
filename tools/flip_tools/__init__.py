"""somersault orchestration tools: the stand-ins for `ros2 launch`, `ros2 service call`,
`ros2 bag record` and the run analysis, built on rclpy and the `rosbags` library.

Modules that import no ROS: bag, summary, plots. Modules that do: launcher, recorder, rosenv
(rclpy is imported lazily inside functions where possible so `flip plan` needs no ROS).
"""
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
