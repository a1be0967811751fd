"""The subroutines of Algorithm 1 (Acar, Choset and Lee), one module each.

:mod:`coverage_pkg.algorithm1` holds Algorithm 1 itself (``PaperPlanner``: the main loop that
calls these); each module here is one subroutine, written as a mixin of ``PaperPlanner`` that
works on the planner's state (the graph ``N, E``, the ring's latest sweep, the primitive being
driven):

* :mod:`~coverage_pkg.paper.graph_nodes`: the nodes of the hierarchical decomposition graph
  (``Node``, ``MorseCell``, ``Branch``);
* :mod:`~coverage_pkg.paper.sense_events`: the events the ring senses (cusp and meet points),
  merged with known ones and handed to the subroutine they belong to;
* :mod:`~coverage_pkg.paper.node_creation`: ``CreateNode(x, D(x))`` and the edges carrying cusp
  points (L, F);
* :mod:`~coverage_pkg.paper.morse_coverage`: ``MorseDecompCoverage(n, L, F)``;
* :mod:`~coverage_pkg.paper.trace_gvd`: ``TraceGVD(n, L, F)``;
* :mod:`~coverage_pkg.paper.find_uncovered`: ``FindUncoveredNode(N)`` and the path to x(n)
  along the robot's traced paths.
"""
