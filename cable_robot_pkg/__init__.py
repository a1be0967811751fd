"""cable_robot_pkg package."""
