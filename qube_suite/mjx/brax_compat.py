"""What Brax 0.14.2 needs from JAX and recent JAX no longer has.

Brax 0.14.2's PPO replicates its training state with `jax.device_put_replicated`,
which JAX removed in 0.10; `ensure_device_put_replicated` gives it back, with its
documented meaning (a stacked copy of each leaf, one slice per device), when the
installed JAX lacks it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

PMAP_AXIS = "i"
"""The device axis's name: Brax's PPO maps its training over the devices under this name, and an
array carries its mesh's axis names in its type, so copies made under another name would make the
training and evaluation functions compile again when they meet the arrays of the first pmapped call."""


def device_put_replicated(tree, devices):
    """`tree` with each leaf stacked `len(devices)` times along a new first axis, slice i on devices[i]."""
    mesh = jax.sharding.Mesh(np.array(devices), (PMAP_AXIS,))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec(PMAP_AXIS))
    return jax.tree.map(lambda leaf: jax.device_put(jnp.stack([jnp.asarray(leaf)] * len(devices)), sharding),
                        tree)


def ensure_device_put_replicated() -> None:
    """Install `device_put_replicated` as `jax.device_put_replicated` if JAX has none."""
    if not hasattr(jax, "device_put_replicated"):
        jax.device_put_replicated = device_put_replicated
