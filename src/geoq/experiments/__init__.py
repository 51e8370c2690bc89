"""Experiments: one module per figure (data only), the sweep runner, configs, the report."""

__all__: list[str] = []
