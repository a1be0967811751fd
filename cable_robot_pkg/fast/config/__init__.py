"""FAST parameter file (fast.yaml) shipped with cable_robot_pkg.fast (package data)."""
