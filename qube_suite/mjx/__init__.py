"""The simulated Qube on MJX (MuJoCo in JAX): thousands of worlds on one GPU, for training at scale.

Needs the `jax` extra (`pip install "qube_suite[jax]"`); nothing else in the package
imports JAX. The same `qube.xml`, voltage path, physical parameters, sensor and
actuator effects and task rules as the numpy `qube` domain, behind a functional
API in the style of Brax and MuJoCo Playground:

    from qube_suite.mjx import environment
    env = environment.QubeMjx("swingup", randomization="sim2real")
    state = env.reset(key)              # one world; jax.vmap for many
    state = env.step(state, action)     # action in [-1, 1]: voltage / voltage_limit

`qube_suite.mjx.training` trains on it with Brax's PPO and writes the project's
numpy policy files.
"""
