"""Qube domains: `qube` (MuJoCo simulation). The interface they share is in `interface`."""
