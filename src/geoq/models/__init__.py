"""Learned models of a task's dynamics, and planning through them.

:class:`GPDynamicsModel` learns one step of a task (the state change, the reward, the
termination) with one sparse online GP per output; :class:`CEMPlanner` chooses
actions by the cross-entropy method over the model's predicted returns
(:func:`model_returns`), closed by a value such as the agent's ``Q``.
"""

from geoq.models.dynamics import GPDynamicsModel, ModelSettings
from geoq.models.planner import CEMPlanner, PlannerSettings, model_returns

__all__ = ["CEMPlanner", "GPDynamicsModel", "ModelSettings", "PlannerSettings", "model_returns"]
