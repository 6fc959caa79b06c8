"""cassie_model: Cassie with a pelvis flywheel (Xiong & Ames, bipedal somersault), no ROS.

:mod:`robot_params` (the parameter table, Table I's flywheels, robot variants) and
:mod:`motor_limits` (the torque–speed envelope u_lb(q̇) ≤ u ≤ u_ub(q̇)) need numpy only; :mod:`model`
(MJCF export, scenarios, MuJoCo build, standing state and its figures), :mod:`pinocchio_map` (the
MuJoCo <-> Pinocchio state mapping) and :mod:`urdf` (URDF from the compiled model) build with MuJoCo.
"""
