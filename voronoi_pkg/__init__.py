"""Simplified Voronoi diagrams for motion planning of quadratically-solvable Gough-Stewart
platforms (Vaca, Aranda & Thomas).

Modules, in reading order:

* :mod:`~voronoi_pkg.predicates` - determinant predicates, pure-condition and
  basic-contact AND-OR trees, their fusion (sections 1-3);
* :mod:`~voronoi_pkg.distance` - the measure rho (min = AND, max = OR, - = NOT) and the
  active leaf (section 4);
* :mod:`~voronoi_pkg.planar` - the planar robot and scene of section 6;
* :mod:`~voronoi_pkg.diagram` - the simplified Voronoi diagram per orientation slice
  and its roadmap across orientations (section 5);
* :mod:`~voronoi_pkg.planner` - retraction onto the diagram, search, dense verification;
* :mod:`~voronoi_pkg.spatial321` - the 3-2-1 platform of Fig. 1 in a polyhedral scene
  (contact predicates, containment, leg-leg contacts, leg-length limits, rho);
* :mod:`~voronoi_pkg.spatial321_roadmap` - its planner: rho-gradient retraction to the
  ties of two contact predicates, roadmap edges traced on the diagram, dense verification;
* :mod:`~voronoi_pkg.figures` - Figs. 2 and 3 as images.

Only :mod:`~voronoi_pkg.planner_node` imports rclpy.
"""
