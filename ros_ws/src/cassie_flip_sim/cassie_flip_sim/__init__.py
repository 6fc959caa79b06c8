"""cassie_flip_sim: MuJoCo simulation of Cassie with a pelvis flywheel (Xiong & Ames, bipedal somersault).

Plain-Python modules (no ROS): robot_params (parameter table), model (MJCF export, scenarios,
MjModel, standing state, Pinocchio mapping), motor_limits, contacts, simulator, render.
"""
