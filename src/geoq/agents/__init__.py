"""Control: agents that learn to act from a GP Q-function (beyond the paper).

* :mod:`geoq.agents.gpq`: :class:`GPQAgent`, online GP Q-learning with fitted-Q phases.
* :mod:`geoq.agents.acquisition`: candidate actions and acquisitions (pure functions).
* :mod:`geoq.agents.fitted_q`: fitted Q-iteration on the sparse GP's basis.
* :mod:`geoq.agents.config`: :class:`GPQConfig`, every setting of the agent, validated.
* :mod:`geoq.agents.graph_replay`: transitions imagined by the JC12 eq. 2 graph
  (``replay="graph"``).
* :mod:`geoq.agents._covariance_cache`: the fitted-Q phases' covariances, kept between phases.
* :mod:`geoq.agents.buffer`: the stored transitions and episode records.
* :mod:`geoq.agents._persist`: the agent's ``.npz`` file format.

``agents`` may import ``gp``, ``kernels``, ``learners`` and ``tasks``; never ``experiments``.
"""

from geoq.agents.buffer import EpisodeRecord
from geoq.agents.config import GPQConfig
from geoq.agents.gpq import GPQAgent

__all__ = ["EpisodeRecord", "GPQAgent", "GPQConfig"]
