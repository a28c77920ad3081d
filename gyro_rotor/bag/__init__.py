"""rosbag2 MCAP I/O: message definitions, QoS text, writer, reader, recovery (pure)."""
