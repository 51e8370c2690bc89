"""The agent's ``policy-net`` search settings replaced for a whole run, CLI included.

With this folder on ``PYTHONPATH``, Python imports this module at start-up in every
process (a parallel sweep's workers too), and ``GEOQ_BRANCH``, a JSON object of
:class:`~geoq.models.PolicyGradientSettings` fields, replaces those fields of
:data:`geoq.agents.policy_planning.BRANCH` (what every ``FeedbackPlanning`` made after
reads), e.g. the second, whole-horizon climb of issue 46's part fifteen::

    PYTHONPATH=research/variants GEOQ_BRANCH='{"whole_steps": 100}' \\
        geoq bench-control --env HalfCheetah-v5 --seeds 5 --timesteps 5000 \\
        --eval-every 500 --eval-episodes 10 --config defaults.json -j 2

Without ``GEOQ_BRANCH`` it changes nothing. A research tool, not the package: the
variants it makes are the design notes' "tried" rows, not defaults.
"""

from __future__ import annotations

import json
import os
from dataclasses import replace

_FIELDS = os.environ.get("GEOQ_BRANCH")
if _FIELDS:
    import geoq.agents.policy_planning as _planning

    _planning.BRANCH = replace(_planning.BRANCH, **json.loads(_FIELDS))

if __name__ == "__main__":  # ``--help``: say what it does
    print(__doc__)
