"""Learning to control a task: ``geoq train`` (:func:`.training.train`), ``geoq evaluate``
(:func:`.evaluation.evaluate_agent`, :mod:`.video`), ``geoq bench-control``
(:func:`.benchmark.run_control_benchmark`) and ``geoq control-suite``
(:func:`.suite.run_control_suite`).

The greedy evaluations (:mod:`.evaluation`) are shared with the baselines
(:mod:`.baselines`, SB3's SAC); :mod:`.visits` and :mod:`.plotting` draw the results.
"""

__all__: list[str] = []
