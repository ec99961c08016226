"""Learned policies, run by numpy (no torch needed): shipped ones by name, others from files.

    from qube_suite.policies import load_policy, shipped
    policy = load_policy("ppo:balance")              # or a path to a policy file
    voltage = policy(observation)                    # any observation of the policy's task
    shipped()                                        # {"ppo:balance": path, ...}

Shipped policies are the pendulum's `<algo>_<task>.npz` files (`qube_suite/devices/qube/policies/`),
trained with `qube-suite train` (see docs/reinforcement-learning.md); the file format is described in
`qube_suite.policies.mlp`.
"""

from __future__ import annotations

import pathlib

from qube_suite.policies.mlp import MLPPolicy, load, save

DIRECTORY = pathlib.Path(__file__).resolve().parent.parent / "devices" / "qube" / "policies"
"""Where the shipped policy files are: the pendulum's folder."""


def shipped() -> dict[str, pathlib.Path]:
    """Shipped policies: spec ("ppo:swingup") -> file path."""
    return {path.stem.replace("_", ":", 1): path for path in sorted(DIRECTORY.glob("*.npz"))}


def names_a_policy(spec: str | pathlib.Path) -> bool:
    """Whether `spec` names a policy `load_policy` would try: a shipped one, or a file (an existing
    path, or one ending in .npz, so that a missing policy file is reported as missing)."""
    path = pathlib.Path(str(spec)).expanduser()
    return str(spec) in shipped() or path.suffix == ".npz" or path.exists()


def load_policy(spec: str | pathlib.Path) -> MLPPolicy:
    """The policy `spec` names: a shipped policy ("ppo:swingup") or the path of a policy file.

    Raises ValueError for an unknown name or a missing, corrupt or invalid file.
    """
    text = str(spec)
    available = shipped()
    if text in available:
        return load(available[text], name=text)
    if names_a_policy(text):
        return load(pathlib.Path(text).expanduser())
    raise ValueError(f"unknown policy {text!r}: shipped policies are {', '.join(available) or 'none'}, "
                     "or give the path of a .npz policy file")


__all__ = ["DIRECTORY", "MLPPolicy", "load", "load_policy", "names_a_policy", "save", "shipped"]
