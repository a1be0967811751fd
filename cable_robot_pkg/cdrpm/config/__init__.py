"""KNTU robot descriptions (kntu_*.yaml) shipped with cable_robot_pkg.cdrpm (package data)."""
