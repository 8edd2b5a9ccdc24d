"""Reading and writing rosbags as plain arrays (rosbags, no ROS install)."""
