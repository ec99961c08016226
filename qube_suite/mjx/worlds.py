"""Each simulated world's plant and effect settings, drawn on the host by the numpy randomization code.

A `Worlds` holds an MJX model and the settings of the sensor and actuator effects,
for one world or, batched along a leading axis, for many (`draw`). The draws are
`qube_suite.randomization`'s own (`sampling.sample`, with world i's random state
seeded `seed + i`), written into MuJoCo models by the numpy domain's own
`write_parameters`: the JAX backend has no second definition of a preset, a
distribution or a parameter's place in the model. Worlds keep their draw for a
whole training run (as MuJoCo Playground's domain randomization does), where the
numpy domains draw again at every episode; thousands of worlds cover the
distribution instead.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import mjx

from qube_suite.devices.qube import batch as qube_batch
from qube_suite.devices.qube import simulation as qube
from qube_suite.randomization.config import Randomization
from qube_suite.randomization.distributions import Distribution
from qube_suite.randomization.sampling import sample
from qube_suite.velocity_filter import VelocityFilter

EFFECTS = ("quantization", "velocity_filter", "observation_noise", "observation_delay", "action_delay",
           "voltage_offset", "dead_zone", "saturation", "control_jitter")
"""Effects the JAX backend applies, in the numpy domains' order (`randomization.catalog.EFFECTS`)."""
DELAYS = ("observation_delay", "action_delay")
"""Effects that are delay lines (`randomization.delays`), whose settings give a number of control steps."""
UNSUPPORTED_EFFECTS: dict[str, str] = {}
"""Effects it does not apply, with the reason (none at present): a config naming one is refused."""

FRICTION_PARAMETERS = ("arm_friction", "pendulum_friction")
"""Parameters that need MuJoCo's constraint stage, on for every world when any draws them."""
SOLVER_ITERATIONS = 4
"""Newton iterations of the friction constraints (at most; MuJoCo's C step allows 100 but converges in
one or two on the Qube's two friction rows, tests/test_mjx.py): a batch of worlds runs as many as its
slowest world, so the bound is what a step costs on a GPU."""
LINE_SEARCH_ITERATIONS = 8


@struct.dataclass
class Worlds:
    """One world's plant and effect settings (or many, each field with a leading world axis).

    `resolution`: encoder step (rad), 0 for exact angles; `filter_pole`, `filter_gain`:
    the velocity filter's pole and gain (1/s), `velocity_filter.filtered_velocity`;
    `noise_std`: [theta, alpha, dtheta, dalpha] (rad, rad/s); `observation_delay_steps`,
    `delay_steps`: observation and action delays (control steps); `voltage_offset`,
    `dead_zone`, `saturation` (V; `saturation` infinite when the effect is off);
    `jitter_fraction`: the control period's largest relative change (0 when off).
    """

    model: mjx.Model
    resolution: jax.Array
    filter_pole: jax.Array
    filter_gain: jax.Array
    noise_std: jax.Array
    observation_delay_steps: jax.Array
    delay_steps: jax.Array
    voltage_offset: jax.Array
    dead_zone: jax.Array
    saturation: jax.Array
    jitter_fraction: jax.Array


def check_config(config: Randomization) -> None:
    """ValueError naming an effect of `config` the JAX backend does not apply, and why."""
    for name in config.effects:
        if name not in EFFECTS:
            why = UNSUPPORTED_EFFECTS.get(name, "it is not written for JAX yet")
            raise ValueError(f"the JAX backend does not apply the effect {name!r}: {why}")


def max_delay_steps(config: Randomization, effect: str, control_frequency: float) -> int:
    """The longest delay (control steps) `config` can draw for `effect` (one of `DELAYS`) at
    `control_frequency` (Hz): the delay line's length less one."""
    settings = config.effects.get(effect)
    if settings is None:
        return 0
    largest = {key: value.bounds()[1] if isinstance(value, Distribution) else value
               for key, value in settings.items()}
    return _delay_steps(largest, 1.0 / control_frequency)


def max_jitter_fraction(config: Randomization) -> float:
    """The largest control-jitter fraction `config` can draw (0 without the effect)."""
    fraction = config.effects.get("control_jitter", {}).get("fraction", 0.0)
    return float(fraction.bounds()[1] if isinstance(fraction, Distribution) else fraction)


def _delay_steps(settings: Mapping, control_period: float) -> int:
    """A delay's control steps from its drawn settings, as `randomization.delays.Delay` counts them:
    `steps`, or `seconds` rounded to whole control periods."""
    if "seconds" in settings:
        return int(np.rint(settings["seconds"] / control_period))
    return int(settings.get("steps", 1))


def template_model(control_frequency: float, config: Randomization) -> mujoco.MjModel:
    """The Qube's model (`qube_batch.physics_model`) with the constraint stage and friction rows on
    when `config` draws friction: MJX fixes which constraint rows exist when the model is put on the
    device, so every world must have them (a row with 0 N m of friction does nothing)."""
    model = qube_batch.physics_model(control_frequency)
    if any(name in config.parameters for name in FRICTION_PARAMETERS):
        scratch = mujoco.MjData(model)
        qube.write_parameters(model, scratch, {name: 1e-9 for name in FRICTION_PARAMETERS})
    model.opt.iterations, model.opt.ls_iterations = SOLVER_ITERATIONS, LINE_SEARCH_ITERATIONS
    return model


def draw(config: Randomization, count: int | None, seed: int, control_frequency: float
         ) -> tuple[Worlds, Worlds | None]:
    """`count` worlds drawn from `config` (world i from `RandomState(seed + i)`), batched, and the
    `in_axes` that vmaps over them; `count` None: one world drawn from `seed`, unbatched, and None.
    """
    check_config(config)
    control_period = 1.0 / control_frequency
    template = template_model(control_frequency, config)
    scratch = mujoco.MjData(template)
    draws = [sample(config, np.random.RandomState(seed + world)) for world in range(count or 1)]
    models = []
    for drawn in draws:
        model = copy.copy(template)
        overrides = dict(drawn.parameters)
        for name in FRICTION_PARAMETERS:  # keep every world's friction rows (see template_model)
            overrides[name] = max(overrides.get(name, 0.0), 1e-9) if name in config.parameters else 0.0
        qube.write_parameters(model, scratch, overrides)
        models.append(model)
    settings = [_effect_settings(drawn.effects, control_period) for drawn in draws]
    fields = {name: jnp.asarray(np.stack([value[name] for value in settings])) for name in settings[0]}
    if not count:
        one = {name: value[0] for name, value in fields.items()}
        return Worlds(model=mjx.put_model(models[0]), **one), None
    device_model = mjx.put_model(template)
    batched = _batched_fields(template, models)
    model = device_model.replace(**{name: jnp.asarray(value) for name, value in batched.items()})
    worlds = Worlds(model=model, **fields)
    model_axes = jax.tree.map(lambda _: None, device_model).replace(**{name: 0 for name in batched})
    axes = Worlds(model=model_axes, **{name: 0 for name in fields})
    return worlds, axes


def _batched_fields(template: mujoco.MjModel, models: list[mujoco.MjModel]) -> dict[str, np.ndarray]:
    """Model fields that differ between worlds, stacked: name -> array with a leading world axis."""
    batched = {}
    for name in (field.name for field in dataclasses.fields(mjx.Model)):
        value = getattr(template, name, None)
        if not isinstance(value, np.ndarray) or value.dtype.kind != "f":
            continue
        values = np.stack([getattr(model, name) for model in models])
        if np.any(values != value):
            batched[name] = values
    return batched


def _effect_settings(effects: Mapping[str, Mapping], control_period: float) -> dict[str, np.ndarray]:
    """One world's effect settings as numbers (`Worlds`' fields but the model); absent effects are
    neutral."""
    counts = effects.get("quantization", {}).get("counts_per_revolution")
    cutoff = effects.get("velocity_filter", {}).get("cutoff")
    pole, gain = (0.0, 0.0) if cutoff is None else _filter(cutoff, control_period)
    delays = {name: 0 if name not in effects else _delay_steps(effects[name], control_period)
              for name in DELAYS}
    return {
        "resolution": np.float64(0.0 if counts is None else 2.0 * math.pi / counts),
        "filter_pole": np.float64(pole), "filter_gain": np.float64(gain),
        "noise_std": np.asarray(effects.get("observation_noise", {}).get("std", [0.0] * 4), dtype=np.float64),
        "observation_delay_steps": np.int32(delays["observation_delay"]),
        "delay_steps": np.int32(delays["action_delay"]),
        "voltage_offset": np.float64(effects.get("voltage_offset", {}).get("voltage", 0.0)),
        "dead_zone": np.float64(effects.get("dead_zone", {}).get("voltage", 0.0)),
        "saturation": np.float64(effects.get("saturation", {}).get("voltage", math.inf)),
        "jitter_fraction": np.float64(effects.get("control_jitter", {}).get("fraction", 0.0)),
    }


def _filter(cutoff: float, control_period: float) -> tuple[float, float]:
    discrete = VelocityFilter(control_period, cutoff)
    return float(discrete.pole), float(discrete.gain)
