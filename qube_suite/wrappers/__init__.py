"""Gymnasium views of the qube_suite environments."""

from qube_suite.wrappers.gym_env import QubeEnv, to_gymnasium
from qube_suite.wrappers.registration import (
    GYMNASIUM_IDS,
    HARDWARE_GYMNASIUM_IDS,
    gymnasium_id,
    register_environments,
)
from qube_suite.wrappers.vector_env import QubeVectorEnv

__all__ = ["GYMNASIUM_IDS", "HARDWARE_GYMNASIUM_IDS", "QubeEnv", "QubeVectorEnv", "gymnasium_id",
           "register_environments",
           "to_gymnasium"]
