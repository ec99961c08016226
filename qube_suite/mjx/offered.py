"""Which tasks the JAX backend offers, and why it does not offer the others (no JAX needed to ask)."""

from __future__ import annotations

TASKS = ("swingup", "swingup_sparse", "balance", "balance_sparse", "dampen", "dampen_sparse", "rotor",
         "swingup_follow", "swingup_follow_sparse", "balance_follow", "balance_follow_sparse")
"""Tasks the JAX backend offers: their rules are formulas of the measured state and of the task's
processes' state, which the environment carries (`qube_suite.mjx.processes`)."""
NOT_OFFERED: dict[str, str] = {}
"""Registered tasks it does not offer, with the reason (none at present)."""


def check_task(task: str) -> None:
    """ValueError unless the JAX backend offers `task`, naming the reason where one is known."""
    if task not in TASKS:
        why = NOT_OFFERED.get(task)
        raise ValueError(f"the JAX backend offers the tasks {', '.join(TASKS)}; " + (
            f"not {task!r}: {why}" if why else f"{task!r} is not one of them"))
