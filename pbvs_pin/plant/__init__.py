"""The plants a run steps.

The Pinocchio plant (:mod:`.pinocchio_plant`, the controller's own model with the no-side-slip
constraint) and the independent MuJoCo plant (:mod:`.mujoco_plant` and its kernels, wheels, payload
and support), and the wheel odometry the robot reads.
"""
