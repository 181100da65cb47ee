"""Workspace study of the arms' tools (paper IV, Fig. 4) and the stance it recommends.

- :func:`compute_map`: reachability of the tool at a fixed orientation over a grid in front of
  the robot, per IK branch; the widest horizontal segment per wall distance and overall
  (refined to sub-millimetre), and the largest reachable rectangle per wall distance.
- :func:`best_stance`: how far from a wall to stand to cut the largest hole (or a given one).

Everything is in the neck frame N (x forward = wall distance, y left, z up), in metres.
"""

from hubo_cli.workspace.maps import PAPER_BEST, PAPER_SEGMENT_Q_RAD, WorkspaceMap, compute_map
from hubo_cli.workspace.results import Rectangle, Segment
from hubo_cli.workspace.stance import StanceResult, best_stance

__all__ = ["PAPER_BEST", "PAPER_SEGMENT_Q_RAD", "Rectangle", "Segment", "StanceResult",
           "WorkspaceMap", "best_stance", "compute_map"]
