"""cassie_flip_sim: MuJoCo simulation of Cassie with a pelvis flywheel (Xiong & Ames, bipedal somersault).

Plain-Python modules (no ROS): contacts, foot_wrench, simulator, perturbation, link_transforms, render; the robot
they simulate (parameters, motor envelope, MJCF and URDF) is cassie_model's, the nodes' transport
flip_transport's.
"""
