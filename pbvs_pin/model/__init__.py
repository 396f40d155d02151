"""The robot's model.

Its URDF descriptions assembled into one Pinocchio model (platform, arm, camera), the platform's
kinematics, the servos of eq. (1), its dynamics and manipulability. Nothing here runs a simulation
or a controller; everything above builds on it.
"""
