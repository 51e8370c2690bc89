"""Learned models of a task's dynamics, and planning through them.

:class:`GPDynamicsModel` learns one step of a task (the state change, the reward, the
termination) with one sparse online GP per output; :class:`CEMPlanner` chooses
actions by the cross-entropy method over the model's predicted returns
(:func:`model_returns`), closed by a value such as the agent's ``Q``;
:func:`search_gains` searches a :class:`LinearFeedback` policy by its return through
the model over a long horizon (PILCO's loop).
"""

from geoq.models.dynamics import GPDynamicsModel, ModelSettings
from geoq.models.planner import (
    CEMPlanner,
    PlannerSettings,
    model_returns,
    rollout_outcomes,
    rollout_returns,
)
from geoq.models.policy_gradient import (
    MLPFeedback,
    PolicyGradientSettings,
    search_policy,
    soft_return,
)
from geoq.models.policy_search import (
    LinearFeedback,
    PolicySearchSettings,
    policy_returns,
    search_gains,
)

__all__ = [
    "CEMPlanner",
    "GPDynamicsModel",
    "LinearFeedback",
    "MLPFeedback",
    "ModelSettings",
    "PlannerSettings",
    "PolicyGradientSettings",
    "PolicySearchSettings",
    "model_returns",
    "policy_returns",
    "rollout_outcomes",
    "rollout_returns",
    "search_gains",
    "search_policy",
    "soft_return",
]
