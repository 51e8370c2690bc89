"""The paper's reproduction, ``geoq reproduce`` (:func:`.reproduce.reproduce`).

Tuning (:mod:`.tuning`), the figures' data (:mod:`.fig1`, :mod:`.fig2`, :mod:`.fig3`) and
their plots (:mod:`.plotting`), the claims checked against them (:mod:`.claims`), the
REPORT.md (:mod:`.report`), the presets (:mod:`.config`), the random streams
(:mod:`.seeding`), the rounding probes (:mod:`.rounding`) and the reference test of a
run against a recorded one (:mod:`.reference`).
"""

__all__: list[str] = []
