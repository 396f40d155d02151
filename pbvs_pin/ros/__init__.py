"""The controller on a ROS 2 robot: a node, and a simulated robot behind the same topics.

ROS 2 comes from pip (the ``ros`` extra: ROS 2 Kilted's Python client and one middleware,
Fast DDS, ``ros-kilted-rmw-fastrtps-cpp``); no setup file is sourced. Importing this package
sets ``RMW_IMPLEMENTATION`` to that middleware unless the environment names one, so that
``rclpy``, imported by :mod:`pbvs_pin.ros.node` and :mod:`pbvs_pin.ros.sim_robot`, loads it.
Nothing outside this package imports those modules except the command line, when asked
(:mod:`pbvs_pin.ros.commands`), so the control core never loads ROS. ``ROS_DOMAIN_ID`` and
``ROS_AUTOMATIC_DISCOVERY_RANGE`` are read from the environment, as ROS reads them.

With that middleware it also points ``FASTDDS_DEFAULT_PROFILES_FILE`` at :data:`TRANSPORTS`
unless the environment names a file: shared memory large enough for camera images. With
Fast DDS's defaults, images went over UDP and their bursts dropped the small messages beside
them, each held up to 3 s until sent again (the file's comment has the measurements). A camera
driver in another process needs the same setting for its images (``docs/ros2.md``).
"""

import os
from pathlib import Path

MIDDLEWARE = "rmw_fastrtps_cpp"
"""The middleware the ``ros`` extra installs."""

os.environ.setdefault("RMW_IMPLEMENTATION", MIDDLEWARE)

TRANSPORTS = Path(__file__).with_name("fastdds.xml")
"""Fast DDS profile: shared memory with 16 MB segments, then UDP (the file says why)."""

if os.environ["RMW_IMPLEMENTATION"] == MIDDLEWARE:
    os.environ.setdefault("FASTDDS_DEFAULT_PROFILES_FILE", str(TRANSPORTS))
