"""Names of the frames pbvs_pin adds to or expects in a robot model.

Body axes follow REP-103 (x forward, y left, z up); the camera optical frame follows REP-103's
``_optical`` suffix (z forward, x right, y down).
"""

WORLD = "world"
"""The fixed frame, Pinocchio's ``universe``; z is up."""

DRIVE_FOOTPRINT = "drive_footprint"
"""Frame added under a platform: on the floor, below the drive-axle midpoint, x forward."""

PLATFORM_FRAME = "platform_frame"
"""Frame added above a platform whose forward axis is not its root link's x: same origin, x
forward (:mod:`pbvs_pin.model.platform_frame`)."""

BASE_JOINTS_ROOT = "base_joints_root"
"""A URDF's root link ``world`` renamed, once its base joints are fixed: it moves with the
platform (:func:`pbvs_pin.model.platform_frame.fix_base_joints`)."""

CAMERA_OPTICAL = "camera_optical_frame"
"""Default name of the camera optical frame (z forward, x right, y down)."""

LASER = "laser_link"
"""Default name of the platform's 2D laser rangefinder frame, if the platform has one."""

ODOM = "odom"
"""The odometry's fixed frame (REP-105): the platform pose of ``nav_msgs/Odometry`` is in it."""
