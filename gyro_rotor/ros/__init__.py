"""The ROS 2 nodes and all that imports rclpy: messages, recorder, rotor_sim, rotor_analysis."""
