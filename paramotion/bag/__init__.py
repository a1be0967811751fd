"""rosbag2 MCAP recording and replay: writer, crash-tolerant reader, recorder and player nodes."""
