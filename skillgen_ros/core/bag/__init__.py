"""rosbag2-layout MCAP bags (metadata.yaml + .mcap files of serialized CDR), pure Python.

    BagWriter(path, WriterOptions(...)).add_topic(TopicSpec(...)); .write(topic, cdr, log_ns); .close()
    BagReader(path).messages(topics) -> BagMessage(topic, type, data, log_time_ns, publish_time_ns)
    bag_info(path) / format_info(info)      what `skillgen bag info` prints
    recover_bag(path)                       finalize the files of a killed recording
Skill annotations: an MCAP metadata record named ANNOTATIONS_RECORD, or annotations.yaml beside.
"""
from skillgen_ros.core.bag.writer import (ANNOTATIONS_RECORD, BagSummary, BagWriter, Compression,  # noqa: F401
                                          TopicSpec, WriterOptions)
from skillgen_ros.core.bag.reader import (BagMessage, BagReader, BagTopic, check_installed,  # noqa: F401
                                          message_class)
from skillgen_ros.core.bag.info import SIDECAR_ANNOTATIONS, BagInfo, bag_info, format_info  # noqa: F401
from skillgen_ros.core.bag.recover import recover_bag  # noqa: F401
