"""A test double of Quanser's Python package (`quanser`): only `quanser.hardware` is provided."""
