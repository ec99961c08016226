"""The hardware path: Quanser boards (real, or the compiled substitute in `_hil_sim`)."""
