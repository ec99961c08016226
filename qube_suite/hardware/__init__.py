"""The hardware path: Quanser boards (real, or the compiled substitute in `_hil_sim`)."""

from qube_suite.hardware.estimation import StateEstimator, VelocityFilter

__all__ = ["StateEstimator", "VelocityFilter"]
