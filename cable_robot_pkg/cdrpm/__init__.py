"""Geometric workspace of cable-driven redundant parallel manipulators (KNTU CDRPM).

Implementation of M. M. Aref and H. D. Taghirad, "Geometrical Workspace Analysis of a
Cable-Driven Redundant Parallel Manipulator: KNTU CDRPM" (IROS 2008), plus a wrench-closure
check the paper does not make. Plain numpy, no ROS:

- :mod:`.description`: the robot description file (frame/platform attachment points, sizes).
- :mod:`.kinematics`: inverse kinematics, eqs. (1)-(3), vectorised over poses.
- :mod:`.collisions`: cable-cable (eqs. (4)-(7)), cable-body (eq. (8)) and cable-workpiece
  (section III-C) collision tests, vectorised over poses.
- :mod:`.workspace`: constant-orientation, orientation and total orientation workspaces
  (section IV), accessible percentage eq. (10), the workpiece study of IV-D.
- :mod:`.wrench_closure`: where positive cable tensions can balance any wrench.
"""
