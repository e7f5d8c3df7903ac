"""The persistent semantic object graph and its per-frame association (the paper's Algorithm 2).

A node is one object: id, category, mean 3D position in the map frame, detection
confidence. Each RGB-D frame brings a list of observations (category + map-frame centroid)
and the caller's list of *expected* nodes (those inside the field-of-view polygon that the
depth image says are not occluded). :meth:`ObjectGraph.associate` then updates the graph
and returns the events (added / removed / moved / updated) for the site store.

Two modes, chosen by :attr:`AssociationParams.mode`, each an association policy behind
one interface (:mod:`~bomc_bt.graph.association`):

``paper`` -- Algorithm 2 as written, so its behaviour can be reproduced and compared
  (:mod:`~bomc_bt.graph.paper`).

``robust`` (default) -- our extension where the paper names its own limitations
  (occlusion, missed detections, relocated objects): one-to-one matching, running-average
  refresh, confirmation before deleting and before adding, moves that keep their id,
  object sizes and footprints against duplicates (:mod:`~bomc_bt.graph.robust`).

The parts, one job each:

* :mod:`~bomc_bt.graph.records` -- Node, Observation, Event, AssociationParams;
* :mod:`~bomc_bt.graph.object_graph` -- the node store and change log, the only code that
  changes nodes, and the spatial index kept in step with them;
* :mod:`~bomc_bt.graph.spatial` -- the hash-grid spatial index;
* :mod:`~bomc_bt.graph.footprints` and :mod:`~bomc_bt.graph.extents` -- floor boxes and how
  big each node's object has shown itself;
* :mod:`~bomc_bt.graph.tentative` -- first sightings awaiting confirmation;
* :mod:`~bomc_bt.graph.confusions` -- a new sighting on another category's node;
* :mod:`~bomc_bt.graph.relocations`, :mod:`~bomc_bt.graph.parts` and
  :mod:`~bomc_bt.graph.returns` -- what the end of a pass settles: removals and additions
  that were one object moved, two ends of one object, moves a late neighbour undoes;
* :mod:`~bomc_bt.graph.operator_edits` -- the operator's corrections that both modes
  respect (a relabelled node keeps its label, a deleted one stays out);
* :mod:`~bomc_bt.graph.reference` -- the naive linear-scan paper, the test oracle and the
  benchmark baseline.
"""

from bomc_bt.graph.association import AssociationPolicy
from bomc_bt.graph.geometry import points_in_polygon
from bomc_bt.graph.object_graph import ObjectGraph, make_policy
from bomc_bt.graph.paper import PaperPolicy
from bomc_bt.graph.records import (
    EVENT_KINDS,
    OPERATOR_KINDS,
    PRESENT,
    REMOVED,
    AssociationParams,
    Event,
    Node,
    Observation,
)
from bomc_bt.graph.reference import associate_linear_scan, nodes_in_polygon_linear
from bomc_bt.graph.robust import RobustPolicy
from bomc_bt.graph.spatial import SpatialIndex

__all__ = [
    "EVENT_KINDS", "OPERATOR_KINDS", "PRESENT", "REMOVED", "AssociationParams", "AssociationPolicy", "Event", "Node",
    "ObjectGraph", "Observation", "PaperPolicy", "RobustPolicy", "SpatialIndex", "associate_linear_scan", "make_policy",
    "nodes_in_polygon_linear", "points_in_polygon",
]
