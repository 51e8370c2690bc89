"""The experiments behind the CLI's commands, one subpackage per product.

* :mod:`geoq.experiments.paper`: the paper's reproduction (``geoq reproduce``);
* :mod:`geoq.experiments.suite`: the Fig. 3 protocol on the task suite (``geoq suite``);
* :mod:`geoq.experiments.control`: learning to control a task (``geoq train``,
  ``geoq evaluate``, ``geoq bench-control``, ``geoq control-suite``).

What they share sits beside them: the resumable sweep runner (:mod:`.sweep`), the
statistics over seeds (:mod:`.stats`), how tables and figures are written
(:mod:`.outputs`) and the kernels' colours (:mod:`.style`). The suite builds on the
paper's Fig. 3 cells; control imports neither (``pyproject.toml``'s import contracts).
"""

__all__: list[str] = []
