"""Control: agents that learn to act from a GP Q-function (beyond the paper).

* :mod:`geoq.agents.gpq`: :class:`GPQAgent`, online GP Q-learning with fitted-Q phases.
* :mod:`geoq.agents.acquisition`: candidate actions and acquisitions (pure functions).
* :mod:`geoq.agents.fitted_q`: fitted Q-iteration on the sparse GP's basis.
* :mod:`geoq.agents.buffer`: the stored transitions.

``agents`` may import ``gp``, ``kernels``, ``learners`` and ``tasks``; never ``experiments``.
"""

from geoq.agents.gpq import EpisodeRecord, GPQAgent, GPQConfig

__all__ = ["EpisodeRecord", "GPQAgent", "GPQConfig"]
