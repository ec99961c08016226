"""Feature maps: what a learned policy sees, computed from the standard Qube observation.

A feature map turns a batch of standard observations, shape (n, 4) = [theta,
alpha, dtheta, dalpha] or (n, 5) with theta_target last (rad, rad/s), into the
network's inputs. Training (`qube_suite.training`) and inference
(`qube_suite.policies.mlp`) call the same function, so a policy file only names
its map.

- `trig`: [cos theta, sin theta, cos alpha, sin alpha, dtheta, dalpha], and for
  follow tasks also [theta - theta_target, theta_target]: angles enter through
  their cosine and sine, so alpha's wrap at +-pi is no jump.
- `plain`: the observation as it is, for devices whose observations need no mapping (a device
  names its map: `qube_suite.devices.Device.feature_map`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from qube_suite.tasks.elementwise import array_namespace, cos, sin


def trig(observations: np.ndarray) -> np.ndarray:
    """The `trig` features of observations of shape (n, 4) or (n, 5); float64 (n, 6) or (n, 8). JAX arrays
    (`qube_suite.mjx`) give JAX arrays of their own dtype."""
    namespace = array_namespace(observations)
    if namespace in (None, np):
        observations, namespace = np.asarray(observations, dtype=np.float64), np
    theta, alpha = observations[:, 0], observations[:, 1]
    columns = [cos(theta), sin(theta), cos(alpha), sin(alpha), observations[:, 2], observations[:, 3]]
    if observations.shape[1] == 5:
        target = observations[:, 4]
        columns += [theta - target, target]
    return namespace.stack(columns, axis=1)


def plain(observations: np.ndarray) -> np.ndarray:
    """The observations themselves, shape (n, size), as a new float64 array."""
    return np.array(observations, dtype=np.float64)


FEATURE_MAPS: dict[str, Callable[[np.ndarray], np.ndarray]] = {"trig": trig, "plain": plain}
"""Feature map name -> function of a batch of standard observations."""


