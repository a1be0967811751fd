"""FAST feed-support algorithms (no rclpy): config, cables, wind, focal surface, PID, isolation,
and the PyBullet plant model."""
