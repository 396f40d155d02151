"""Record ROS 2 messages into a rosbag2 bag in MCAP storage, with ``rosbags``.

The messages are serialised by ROS itself (``rclpy.serialization``, CDR) and written with
their type's definition from ``rosbags``' Kilted type store, so that ``rosbags``, ``ros2 bag``
and Foxglove read them back as standard messages.
"""

from __future__ import annotations

from pathlib import Path

from rclpy.serialization import serialize_message
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from pbvs_pin.exceptions import OutputError


def message_type(message: object) -> str:
    """The ROS type name of a message, e.g. ``sensor_msgs/msg/Image``."""
    cls = type(message)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


class BagRecorder:
    """A rosbag2 bag (MCAP) being written; one connection per topic.

    Args:
        path: The bag's folder; must not exist.

    Raises:
        OutputError: If ``path`` exists.
    """

    def __init__(self, path: str | Path) -> None:
        if Path(path).exists():
            raise OutputError(str(path), "exists; a bag is written into a new folder")
        self.typestore = get_typestore(Stores.ROS2_KILTED)
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections: dict[str, object] = {}

    def write(self, topic: str, message: object, t: float) -> None:
        """Record ``message`` on ``topic`` at time ``t`` [s]."""
        connection = self.connections.get(topic)
        if connection is None:
            connection = self.writer.add_connection(
                topic, message_type(message), typestore=self.typestore
            )
            self.connections[topic] = connection
        self.writer.write(connection, round(t * 1e9), serialize_message(message))

    def close(self) -> None:
        """Finish the bag (its metadata)."""
        self.writer.close()
