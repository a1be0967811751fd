"""The nodes of the hierarchical decomposition graph (Section IV-C) as Algorithm 1 builds them.

A *vast* node holds its Reeb graph (Morse cells between critical points) and the boundary
circuits followed at D = delta; a *narrow* node holds its GVD branches and meet points. Edges
``(vast id, narrow id, cusp)`` are kept by :class:`coverage_pkg.algorithm1.PaperPlanner`.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class MorseCell:
    """An edge of a vast node's Reeb graph: a cell between two critical points."""

    id: int
    start: tuple                    # where its first lap is driven from
    sweep: int                      # +1: laps advance along +x, -1: along -x
    prev_span: tuple = None         # (y_lo, y_hi) of the lap before its first one
    opened_by: int = None           # index of the event that opened it
    closed_by: int = None           # ... and of the event that closed it
    parent: int = None              # the cell whose critical point opened it
    resume: tuple = None            # (x, y, dir): a slice to resume beyond an obstacle
    laps: list = field(default_factory=list)   # (x, y_lo, y_hi) per lap driven
    status: str = 'open'            # open, covering, covered, given_up


@dataclass
class Branch:
    """A GVD edge of a narrow node, left from ``start`` along ``heading``."""

    start: tuple
    heading: tuple
    opened_by: int = None
    end: str = None                 # cusp, dead_end, meet, given_up (None: untraced)
    end_xy: tuple = None            # where the trace ended
    end_heading: tuple = None       # the direction it was traced in when it ended
    gap: bool = False               # opened by a gap beside a dead end (TraceGVD._gap_at_end)
    scan: bool = False              # its edges are read by a meet scan at its start (a
    #                                 meet point passed just beyond delta)


@dataclass
class Node:
    """A node of the hierarchical decomposition graph."""

    id: int
    kind: str                       # 'vast' or 'narrow'
    anchor: tuple                   # x(n): where the robot starts covering it
    created_by: int = None          # event index (None: CreateNode at the start)
    closed_by: int = None
    covered: bool = False
    given_up: bool = False
    merged_into: int = None         # vast: the node whose boundary circuit passed its cusp
    circuits: list = field(default_factory=list)    # vast: boundaries to follow at D = delta
    cells: list = field(default_factory=list)       # vast: Morse cells (Reeb graph edges)
    critical: list = field(default_factory=list)    # vast: (x, y, kind, event index)
    branches: list = field(default_factory=list)    # narrow: GVD branches
    meets: list = field(default_factory=list)       # narrow: (x, y, event index)
