"""The controller on a ROS 2 robot: a node, and a simulated robot behind the same topics.

ROS 2 comes from pip (the ``ros`` extra: ROS 2 Kilted's Python client and one middleware,
Fast DDS, ``ros-kilted-rmw-fastrtps-cpp``); no setup file is sourced. Importing this package
sets ``RMW_IMPLEMENTATION`` to that middleware unless the environment names one, so that
``rclpy``, imported by :mod:`pbvs_pin.ros.node` and :mod:`pbvs_pin.ros.sim_robot`, loads it.
Nothing outside this package imports those modules except the command line, when asked
(:mod:`pbvs_pin.ros.commands`), so the control core never loads ROS. ``ROS_DOMAIN_ID`` and
``ROS_AUTOMATIC_DISCOVERY_RANGE`` are read from the environment, as ROS reads them.
"""

import os

MIDDLEWARE = "rmw_fastrtps_cpp"
"""The middleware the ``ros`` extra installs."""

os.environ.setdefault("RMW_IMPLEMENTATION", MIDDLEWARE)
