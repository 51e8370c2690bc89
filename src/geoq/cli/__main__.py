"""``python -m geoq.cli``: the ``geoq`` command."""

from geoq.cli import main

main()
