"""Policy evaluation on the task suite, ``geoq suite`` (:func:`.run.run_suite`).

The paper's Fig. 3 protocol (:mod:`geoq.experiments.paper.fig3`) on every task of
:mod:`geoq.tasks.suite`: the sweep cells (:mod:`.cells`) and the SUITE.md with its
figures (:mod:`.report`).
"""

__all__: list[str] = []
