"""The chain MDP's closed form against value iteration by brute force."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.envs import ChainMDP


@pytest.mark.parametrize(("n", "p", "gamma"), [(5, 0.7, 0.9), (3, 0.2, 0.5), (6, 1.0, 0.8)])
def test_closed_form_is_the_bellman_fixed_point(n: int, p: float, gamma: float) -> None:
    chain = ChainMDP(n_states=n, p_right=p)
    Q = np.zeros((n, 2))
    for _ in range(2000):  # value iteration for the fixed policy, scalar loops
        new = np.zeros_like(Q)
        for s in range(n):
            for k, a in enumerate((-1, 1)):
                nxt = min(max(s + a, 0), n - 1)
                reward = float(s == n - 1) - 0.1 * (a > 0)
                new[s, k] = reward + gamma * ((1 - p) * Q[nxt, 0] + p * Q[nxt, 1])
        Q = new
    np.testing.assert_allclose(chain.q_values(gamma), Q, atol=1e-10)


def test_step_policy_and_start() -> None:
    chain = ChainMDP()
    nxt, r = chain.step(np.array([[0.0], [4.0], [4.0]]), np.array([-1.0, 1.0, -1.0]))
    np.testing.assert_array_equal(nxt[:, 0], [0.0, 4.0, 3.0])
    np.testing.assert_allclose(r, [0.0, 0.9, 1.0])
    a = chain.policy(np.zeros((10000, 1)), np.random.default_rng(0))
    assert np.mean(a > 0) == pytest.approx(0.7, abs=0.02)
    s = chain.start(np.random.default_rng(0), 1000)
    assert set(np.unique(s)) == {0.0, 1.0, 2.0, 3.0, 4.0}
    with pytest.raises(ValueError, match="n_states"):
        ChainMDP(n_states=1)
