"""The online MDP-induced graph over the basis vectors and its exact incremental shortest paths."""

from geoq.graph.mdp_graph import EdgeWeight, MDPGraph

__all__ = ["EdgeWeight", "MDPGraph"]
