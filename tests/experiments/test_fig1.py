"""Fig. 1 data: JC12 eq. 2 as written, edge counts over a range of eps."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from geoq.experiments.paper.fig1 import EDGE_COUNT_COLUMNS, edge_counts_by_eps, relink
from geoq.learners import QGPConfig
from geoq.policies import DEFAULT_POLICY_SIGMA, default_policy
from geoq.rollouts import collect_rollouts

EPS = (0.1, 0.3, 0.5, 0.7, 0.9)


def test_relink_counts_the_pairs_of_eq_2_and_fewer_for_larger_eps():
    rng = np.random.default_rng(5)
    nodes = rng.normal(scale=0.8, size=(40, 3))
    d2 = pdist(nodes, "sqeuclidean")
    counts = []
    for eps in EPS:
        graph = relink(nodes, eps)
        n_edges = graph.adjacency.nnz // 2
        assert n_edges == np.count_nonzero(np.exp(-d2) > eps)  # brute-force oracle of JC12 eq. 2
        counts.append(n_edges)
    assert counts == sorted(counts, reverse=True) and counts[0] > counts[-1]


@pytest.fixture(scope="module")
def rows():
    policy = default_policy(DEFAULT_POLICY_SIGMA)
    rollouts = collect_rollouts(2, 60, policy, np.random.default_rng(0), gamma=0.95)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return edge_counts_by_eps(rollouts, QGPConfig(sigma_sp=0.03), (0.3, 0.5), EPS, 30)


def test_edge_counts_by_eps_rows(rows):
    assert all(list(r) == list(EDGE_COUNT_COLUMNS) for r in rows)
    same = [r for r in rows if r["mode"] == "same nodes"]
    rebuilt = [r for r in rows if r["mode"] == "rebuilt"]
    assert len(same) == 2 * len(EPS) and [r["eps"] for r in rebuilt] == list(EPS)
    for e0 in (0.3, 0.5):
        sub = [r for r in same if r["node_eps"] == e0]
        assert len({r["n_nodes"] for r in sub}) == 1  # one node set, re-linked
        edges = [r["n_edges"] for r in sub]
        assert edges == sorted(edges, reverse=True)
        comps = [r["n_components"] for r in sub]
        assert comps == sorted(comps)  # fewer edges never join components
        # At its own eps the re-linked graph is the GP's graph (same nodes, JC12 eq. 2 only).
        own = next(r for r in sub if r["eps"] == e0)
        built = next(r for r in rebuilt if r["eps"] == e0)
        assert own["n_edges"] == built["n_edges"] and own["n_nodes"] == built["n_nodes"]
