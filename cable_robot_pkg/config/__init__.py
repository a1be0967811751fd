"""Robot descriptions and parameter files shipped with cable_robot_pkg (package data)."""
