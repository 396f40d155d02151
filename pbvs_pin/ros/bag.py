"""Record ROS 2 messages into a rosbag2 bag in MCAP storage, with ``rosbags``.

The messages are built by ROS (``rclpy``'s classes) and serialised (CDR) by ``rosbags`` from
its Kilted type store, which also writes each type's definition into the bag, so that
``rosbags``, ``ros2 bag`` and Foxglove read them back as standard messages. ROS's own
serialiser (Fast CDR) is not used: it pads an empty sequence of 8-byte numbers (a
``JointState`` without efforts) by 4 bytes that ``rosbags`` refuses ("CDR message size
mismatch"), while ROS and Foxglove read ``rosbags``' bytes as their own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from pbvs_pin.exceptions import OutputError


def message_type(message: object) -> str:
    """The ROS type name of a message, e.g. ``sensor_msgs/msg/Image``."""
    cls = type(message)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


NUMBERS = {
    "double": np.float64, "float": np.float32, "int8": np.int8, "uint8": np.uint8,
    "octet": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
    "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64, "boolean": np.bool_,
}  # fmt: skip
"""numpy types of ROS's numeric field types, which ``rosbags`` takes as arrays."""


def store_message(message: Any, typestore: Any) -> Any:
    """The ``rosbags`` message of the type store with an ``rclpy`` message's fields."""
    values = {
        name: _store_value(getattr(message, name), kind, typestore)
        for name, kind in message.get_fields_and_field_types().items()
    }
    return typestore.types[message_type(message)](**values)


def _store_value(value: Any, kind: str, typestore: Any) -> Any:
    """A field's value for ``rosbags``: numeric sequences and arrays as numpy arrays."""
    if hasattr(value, "get_fields_and_field_types"):
        return store_message(value, typestore)
    if kind.startswith("sequence<") or kind.endswith("]"):
        element = kind.removeprefix("sequence<").split(",")[0].split("[")[0].rstrip(">")
        if element in NUMBERS:
            return np.asarray(value, dtype=NUMBERS[element])
        return [_store_value(item, element, typestore) for item in value]
    if isinstance(value, bytes):  # an octet: rclpy holds one byte, rosbags an integer
        return int.from_bytes(value, "little")
    return value


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
        kind = message_type(message)
        raw = self.typestore.serialize_cdr(store_message(message, self.typestore), kind)
        self.write_serialised(topic, kind, bytes(raw), t)

    def write_serialised(self, topic: str, type_name: str, raw: bytes, t: float) -> None:
        """Record a message serialised (CDR) of type ``type_name`` at time ``t`` [s].

        ``type_name`` is ``package/msg/Name``; for messages ROS cannot build here
        (``tf2_msgs``: :mod:`pbvs_pin.ros.tf`).
        """
        connection = self.connections.get(topic)
        if connection is None:
            connection = self.writer.add_connection(topic, type_name, typestore=self.typestore)
            self.connections[topic] = connection
        self.writer.write(connection, round(t * 1e9), raw)

    def close(self) -> None:
        """Finish the bag (its metadata)."""
        self.writer.close()
