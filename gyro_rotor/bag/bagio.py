"""Write and read rosbag2 bags (MCAP storage) the way ``ros2 bag`` on Jazzy does, in pure Python.

The module imports neither rclpy nor message types: messages go in and out as serialized CDR
bytes (``rclpy.serialization.serialize_message`` or ``raw=True`` subscriptions), and
:meth:`BagReader.decoded` decodes them with the ``mcap_ros2`` decoder from the definitions
stored in the bag.

Format decisions (each checked against the rosbag2 Jazzy sources and the readers in tests):

* **Layout.** A bag is a directory ``<name>/`` holding ``<name>_0.mcap`` and
  ``metadata.yaml`` (rosbag2 ``SequentialWriter``). A bare ``.mcap`` file can be read too.
* **MCAP records** (ros2/rosbag2 ``jazzy:rosbag2_storage_mcap/src/mcap_storage.cpp``,
  ``create_topic`` and ``update_metadata``): header profile ``ros2``; one schema per type,
  named by the type (``sensor_msgs/msg/JointState``), encoding ``ros2msg``, data the full
  definition text of :func:`gyro_rotor.bag.msgdefs.message_definition`; one channel per topic,
  message encoding ``cdr``, metadata ``offered_qos_profiles`` (a YAML string) and
  ``topic_type_hash`` (RIHS01 or ``''``); a metadata record ``rosbag2`` with key
  ``serialized_metadata`` (the YAML of the bag metadata, version 9) written at close. The
  summary holds a Statistics record, which ``ros2 bag info`` on a bare ``.mcap`` requires.
  Chunks are uncompressed by default, like rosbag2 (``compression = None``).
* **QoS** (ros2/rosbag2 ``jazzy:rosbag2_storage/src/rosbag2_storage/qos.cpp``): version 9
  writes the policies as strings (``keep_last``, ``reliable``, ``volatile``, ``automatic``)
  and durations as ``{sec, nsec}``; ``metadata.yaml`` holds the list itself, the channel
  metadata the same list dumped to a YAML string. rosbags 0.11.9 (``rosbag2/metadata.py``
  ``parse_qos``) accepts both and pairs the ``metadata.yaml`` topics with the MCAP channels
  only if both parse to equal values, so both are produced from one normalized list.
* **metadata.yaml** (``rosbag2_storage/include/rosbag2_storage/yaml.hpp``, version 9): top key
  ``rosbag2_bagfile_information``; written at open, rewritten (atomically) when a topic is
  added (zero counts) and at close (final counts). After a crash :func:`recover_bag` rewrites
  it from the data.
* **Flushing.** ``mcap.writer.Writer`` keeps the current chunk in memory until it exceeds
  ``chunk_size``. :class:`BagWriter` also ends the chunk as soon as a write arrives more than
  ``flush_interval_s`` after the first message of the chunk, with the public
  ``mcap.writer.Writer.flush()`` (ends the chunk, writes it, flushes the Python buffer). A
  SIGKILL therefore loses at most about ``flush_interval_s`` of messages; the kernel keeps
  written data across a killed process, ``fsync=True`` adds an ``os.fsync`` per flush for power
  loss. A writer that may go idle should call :meth:`BagWriter.flush` from a timer.
* **Reading damaged files.** A file without a valid footer and summary (a killed writer, a
  cut copy) is read record by record from the start; every complete record is used, the first
  incomplete or malformed one ends the scan. The reader then sets ``truncated`` and warns with
  :class:`BagWarning`; it raises :class:`~gyro_rotor.errors.BagError` only when nothing at all
  can be read (missing path, empty directory, not an MCAP file).
"""

from gyro_rotor.bag.metadata import BagWarning, METADATA_VERSION
from gyro_rotor.bag.msgdefs import message_definition, type_hash
from gyro_rotor.bag.qos import normalize_qos, qos_profile_dict
from gyro_rotor.bag.reader import BagReader, open_bag, TopicInfo
from gyro_rotor.bag.recovery import recover_bag, RecoveryReport
from gyro_rotor.bag.writer import BagWriter
from gyro_rotor.errors import BagError

__all__ = [
    'BagError', 'BagWarning', 'BagWriter', 'BagReader', 'TopicInfo', 'RecoveryReport',
    'open_bag', 'recover_bag', 'qos_profile_dict', 'normalize_qos', 'message_definition',
    'type_hash', 'METADATA_VERSION',
]
