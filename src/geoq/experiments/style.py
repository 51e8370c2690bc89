"""What every figure of the experiments shares: one colour and label per kernel."""

from __future__ import annotations

__all__ = ["KERNEL_STYLE"]

#: Colour and label per kernel name, shared by every figure.
KERNEL_STYLE: dict[str, dict[str, str]] = {
    "euclidean": {"color": "tab:blue", "label": "Euclidean (SE)"},
    "nearest": {"color": "tab:orange", "label": "shortest path, nearest (eq. 4)"},
    "interpolated": {"color": "tab:green", "label": "shortest path, interpolated (eq. 5)"},
    "resistance": {"color": "tab:purple", "label": "resistance distance, PD (beyond paper)"},
    "monte_carlo": {"color": "black", "label": "Monte-Carlo Q^pi (ground truth)"},
}
