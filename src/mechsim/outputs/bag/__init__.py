"""rosbag2-compatible MCAP bags: the writer sink, the reader, metadata, repair.

A bag is a directory ``DIR`` holding ``DIR_0.mcap`` and ``metadata.yaml``, exactly as rosbag2's
MCAP storage writes them (ROS_CONVENTIONS §4), so ``ros2 bag info|play``, ``rosbags``,
``mcap`` + ``mcap_ros2``, Foxglove and Rerun read them:

- MCAP profile ``ros2``; one ``ros2msg`` schema per type, holding the full definition text with
  its dependencies read from the environment's ``.msg`` files (``mechsim.outputs.wire``);
- one ``cdr`` channel per topic, metadata ``offered_qos_profiles`` (YAML, version-9 string
  enums, :mod:`.qos`) and ``topic_type_hash`` (RIHS01);
- messages as DDS carries them (``mechsim.outputs.wire``); ``log_time`` = ``publish_time`` = the
  message stamp (simulation time + offset), so ``ros2 bag play --clock`` reproduces simulation
  time;
- zstd-compressed chunks, message indexes and a summary; the ``rosbag2`` metadata record
  (``serialized_metadata``) at open and at close; ``metadata.yaml`` version 9 with
  ``custom_data`` describing the run (:mod:`.metadata`).

One module per job: :mod:`.qos`,
:mod:`.metadata` (BagMetadata, safe YAML out, checked YAML in), :mod:`.lock` (a bag being
written is left alone), :mod:`.mcapfile` (the MCAP writer), :mod:`.writer` (:class:`BagWriter`),
:mod:`.mcapread` (the bounded MCAP reader), :mod:`.reader` (metadata, messages, ``bag info``),
:mod:`.repair`. File safety (exclusive temporaries, atomic renames,
bounded reads) is :mod:`mechsim.files`.
"""

from mechsim.outputs.bag.lock import LOCK_FILE, BagLock, check_not_in_use, live_holder
from mechsim.outputs.bag.metadata import (
    METADATA_FILE,
    ROS_DISTRO,
    ROSBAG2_VERSION,
    SERIALIZATION,
    STORAGE_ID,
    SYSTEM_INFO,
    BagStats,
    TopicInfo,
    bag_metadata,
    dump_yaml,
    parse_metadata,
    storage_file_name,
    system_info_custom,
    topic_qos,
)
from mechsim.outputs.bag.qos import INFINITE, qos_dict, qos_profile
from mechsim.outputs.bag.reader import (
    BagMessage,
    bag_files,
    check_bag,
    check_storage,
    describe,
    read_messages,
    read_metadata,
)
from mechsim.outputs.bag.repair import RepairResult, repair_bag
from mechsim.outputs.bag.writer import (
    CHUNK_SIZE,
    FLUSH_WALL_S,
    PROFILE,
    SCHEMA_ENCODING,
    BagWriter,
    claim_bag_dir,
    expand_path,
)
from mechsim.outputs.wire import (
    SEPARATOR,
    message_class,
    message_definition,
    type_description_hash,
)

__all__ = [
    "CHUNK_SIZE", "FLUSH_WALL_S", "INFINITE", "LOCK_FILE", "METADATA_FILE",
    "PROFILE", "ROSBAG2_VERSION", "ROS_DISTRO", "SCHEMA_ENCODING", "SEPARATOR", "SERIALIZATION",
    "STORAGE_ID", "SYSTEM_INFO", "BagLock", "BagMessage", "BagStats", "BagWriter",
    "RepairResult", "TopicInfo", "bag_files", "bag_metadata", "check_bag", "check_storage",
    "check_not_in_use", "claim_bag_dir", "describe", "dump_yaml", "expand_path",
    "live_holder", "message_class", "message_definition", "parse_metadata", "qos_dict",
    "qos_profile", "read_messages", "read_metadata", "repair_bag", "storage_file_name",
    "system_info_custom", "topic_qos", "type_description_hash",
]
