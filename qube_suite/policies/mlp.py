"""A learned policy run by numpy: observation features, normalisation, an MLP, the voltage.

A policy file (`.npz`, written by `save`, read by `load`) holds plain arrays and
one JSON record, nothing pickled:

- `weight_0`, `bias_0`, ..., `weight_k`, `bias_k`: the layers of the actor's
  mean, `weight_i` of shape (outputs, inputs) as in torch; the hidden layers are
  followed by `activation`, the last one is linear;
- `observation_mean`, `observation_var`: the running statistics of the features
  during training; features are normalised as (f - mean) / sqrt(var + epsilon)
  and clipped to +-clip;
- `meta`: JSON with `format` (2), `feature_map` (`qube_suite.policies.features`),
  `activation` ("tanh", "relu" or "swish" = x sigmoid(x)), `squash` (SAC and
  Brax PPO: the output goes through tanh and is scaled from [-1, 1] to
  [-voltage_limit, voltage_limit]; SB3 PPO: the output is the voltage),
  `epsilon`, `clip`, `voltage_limit` (V), `observation_size` (4, or 5 with a
  target), `history` (the number k of past observations and voltages the
  network also sees, 0 for none: `qube_suite.policies.history`),
  `task`, `algo`, and the record of its training; `action_size`, only for a device with
  several motors: the number of voltages the last layer gives (1 without it).

Format 1 is format 2 without `history` (no history); this module reads both and
refuses other formats, and files whose layers do not fit their features and
history, with a `ValueError` naming the mismatch.

The action is the deterministic one, the mean of the trained Gaussian, clipped to
+-voltage_limit.
"""

from __future__ import annotations

import json
import math
import numbers
import pathlib
import zipfile
import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from qube_suite.conventions import ObservationLayout
from qube_suite.policies.features import FEATURE_MAPS
from qube_suite.policies.history import History, input_size

FORMAT = 2
READABLE_FORMATS = (1, 2)
ACTIVATIONS = {"tanh": np.tanh, "relu": lambda x: np.maximum(x, 0.0),
               "swish": lambda x: x / (1.0 + np.exp(-x))}
REQUIRED_META = ("format", "feature_map", "activation", "squash", "epsilon", "clip", "voltage_limit",
                 "observation_size", "task", "algo")


class MLPPolicy:
    """A learned policy with the controller interface: `voltage = policy(observation)`.

    Takes an observation of its task (a dm_env mapping or a flat Gymnasium vector, of
    `observation_layout`) and returns the motor voltage (V), within +-`voltage_limit`.
    A policy with `history` > 0 remembers its last observations and voltages: call
    `reset` before each episode; others keep no memory.
    """

    def __init__(self, weights: Sequence[np.ndarray], biases: Sequence[np.ndarray],
                 observation_mean: np.ndarray, observation_var: np.ndarray, meta: Mapping[str, Any],
                 name: str = "policy"):
        if not isinstance(meta, Mapping):
            raise ValueError(f"meta must be a mapping (a JSON object), got {type(meta).__name__}")
        self.weights = [_real_array(w, f"weight_{i}") for i, w in enumerate(weights)]
        self.biases = [_real_array(b, f"bias_{i}") for i, b in enumerate(biases)]
        self.observation_mean = _real_array(observation_mean, "observation_mean")
        self.observation_var = _real_array(observation_var, "observation_var")
        self.meta = dict(meta)
        self.name = name
        _check(self.weights, self.biases, self.observation_mean, self.observation_var, self.meta)
        self.tasks = (self.meta["task"],)
        self.voltage_limit = float(self.meta["voltage_limit"])
        self._features = FEATURE_MAPS[self.meta["feature_map"]]
        self._activation = ACTIVATIONS[self.meta["activation"]]
        self._scale = 1.0 / np.sqrt(self.observation_var + float(self.meta["epsilon"]))
        self._clip = float(self.meta["clip"])
        self._size = int(self.meta["observation_size"])
        self.observation_layout = ObservationLayout(target=self._size == 5) \
            if self.meta["feature_map"] == "trig" else None
        """How calls read observations: by default the layout the policy was trained on (its file's
        `observation_size`); set the task's (`QubeTask.observation_layout`) to run it on another,
        e.g. the trig one. None for another feature map (a device's `plain` policy), which reads its
        observation's values in order."""
        self.history = int(self.meta.get("history", 0))
        self.action_size = int(self.meta.get("action_size", 1))
        """Voltages per action: 1, or one per motor of a device with several."""
        self._memory: History | None = None
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self) -> None:
        """Forget the history: the next call starts an episode."""
        self._memory, self._last = None, None

    def actions(self, observations: np.ndarray) -> np.ndarray:
        """Voltages (V), shape (n,), for standard observations of shape (n, 4) or (n, 5) of n worlds;
        shape (n, action_size) for a policy of several voltages.

        With `history`, successive calls are successive steps of the same n worlds
        (since the last `reset`, or since a call with a different n).
        """
        features = self._features(observations)
        if self.history:
            features = self._remember(features)
        x = np.clip((features - self.observation_mean) * self._scale, -self._clip, self._clip)
        last = len(self.weights) - 1
        for i, (weight, bias) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = x @ weight.T + bias
            if i < last:
                x = self._activation(x)
        volts = x[:, 0] if self.action_size == 1 else x
        if self.meta["squash"]:
            volts = np.tanh(volts) * self.voltage_limit
        volts = np.clip(volts, -self.voltage_limit, self.voltage_limit)
        if self.history:
            self._last = (self._last[0], volts)
        return volts

    def _remember(self, features: np.ndarray) -> np.ndarray:
        """The inputs with history for `features`, after recording the previous step."""
        if self._memory is None or len(self._memory.voltages) != len(features):
            self._memory = History(self.history, len(features), features.shape[1])
            self._memory.start(features)
        else:
            self._memory.push(*self._last)
        self._last = (features, None)
        return self._memory.inputs(features)

    def __call__(self, observation: Any) -> float | np.ndarray:
        """Motor voltage (V) for one observation of the policy's task; an array of `action_size`
        voltages for a policy of several."""
        if self.meta["feature_map"] != "trig":
            row = flat_values(observation, self._size)
        else:
            state, target = self.observation_layout.split(observation)
            row = np.append(state, target) if self._size == 5 else state
        volts = self.actions(row[None, :])[0]
        return float(volts) if self.action_size == 1 else volts

    def close(self) -> None:
        """Nothing to release."""


def flat_values(observation: Any, size: int) -> np.ndarray:
    """The values of an observation in order (a dm_env mapping's entries concatenated, or a flat
    vector); ValueError unless there are `size`."""
    values = observation.values() if isinstance(observation, Mapping) else [observation]
    row = np.concatenate([np.ravel(np.asarray(value, dtype=np.float64)) for value in values])
    if row.size != size:
        raise ValueError(f"the policy takes observations of {size} values, got {row.size}")
    return row


def save(policy: MLPPolicy, path: str | pathlib.Path) -> pathlib.Path:
    """Write `policy` to `path` (a `.npz` file) and return the path."""
    path = pathlib.Path(path)
    arrays = {"observation_mean": policy.observation_mean, "observation_var": policy.observation_var,
              "meta": np.array(json.dumps(policy.meta, sort_keys=True))}
    for i, (weight, bias) in enumerate(zip(policy.weights, policy.biases, strict=True)):
        arrays[f"weight_{i}"], arrays[f"bias_{i}"] = weight.astype(np.float32), bias.astype(np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as file:
        np.savez_compressed(file, **arrays)
    return path


def load(path: str | pathlib.Path, name: str | None = None) -> MLPPolicy:
    """The policy in the file at `path`; ValueError if it is missing, not a policy file or corrupt."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise ValueError(f"no policy file at {path}")
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{path} is not a policy file (not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as arrays:
            meta = json.loads(str(arrays["meta"]))
            layers = sum(1 for key in arrays.files if key.startswith("weight_"))
            weights = [arrays[f"weight_{i}"] for i in range(layers)]
            biases = [arrays[f"bias_{i}"] for i in range(layers)]
            mean, var = arrays["observation_mean"], arrays["observation_var"]
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as error:
        raise ValueError(f"{path} is not a readable policy file ({type(error).__name__}: {error})") from error
    try:
        return MLPPolicy(weights, biases, mean, var, meta, name=name or path.stem)
    except ValueError as error:
        raise ValueError(f"{path} is not a valid policy file: {error}") from error


def _real_array(values, name: str) -> np.ndarray:
    """`values` as float64; ValueError unless they are real numbers (complex, text, objects refused)."""
    array = np.asarray(values)
    if array.dtype.kind not in "fiu":
        raise ValueError(f"{name} must hold real numbers, got dtype {array.dtype}")
    return array.astype(np.float64)


def _check(weights: list[np.ndarray], biases: list[np.ndarray], mean: np.ndarray, var: np.ndarray,
           meta: dict[str, Any]) -> None:
    """ValueError unless the arrays and the record make a policy this module can run."""
    missing = [key for key in REQUIRED_META if key not in meta]
    if missing:
        raise ValueError(f"meta lacks {', '.join(missing)}")
    if meta["format"] not in READABLE_FORMATS:
        raise ValueError(f"format {meta['format']!r}; this qube_suite reads formats "
                         f"{', '.join(map(str, READABLE_FORMATS))} (a newer qube_suite wrote it?)")
    history = meta.get("history", 0)
    if meta["format"] == 1 and "history" in meta:
        raise ValueError("format 1 has no history; a policy with history is format 2")
    if not (isinstance(history, int) and history >= 0):
        raise ValueError(f"history must be an integer >= 0, got {history!r}")
    outputs = meta.get("action_size", 1)
    if not (isinstance(outputs, int) and not isinstance(outputs, bool) and outputs >= 1):
        raise ValueError(f"action_size must be a positive integer, got {outputs!r}")
    if outputs > 1 and history:
        raise ValueError("a policy with history gives one voltage; this one has action_size "
                         f"{outputs}")
    if meta["feature_map"] not in FEATURE_MAPS:
        raise ValueError(f"unknown feature map {meta['feature_map']!r}; known: {', '.join(FEATURE_MAPS)}")
    if meta["activation"] not in ACTIVATIONS:
        raise ValueError(f"unknown activation {meta['activation']!r}; known: {', '.join(ACTIVATIONS)}")
    size = meta["observation_size"]
    if meta["feature_map"] == "trig" and size not in (4, 5):
        raise ValueError(f"observation_size must be 4 or 5, got {size!r}")
    if not (isinstance(size, int) and not isinstance(size, bool) and size > 0):
        raise ValueError(f"observation_size must be a positive integer, got {size!r}")
    if not weights or len(weights) != len(biases):
        raise ValueError("no layers, or weights and biases that do not pair up")
    features = FEATURE_MAPS[meta["feature_map"]](np.zeros((1, meta["observation_size"]))).shape[1]
    inputs = input_size(features, history)
    if mean.shape != (inputs,) or var.shape != (inputs,) or np.any(var < 0):
        raise ValueError(f"normalisation statistics must be {inputs} values (variances >= 0) for "
                         f"{features} features and a history of {history}, got {mean.size}")
    for i, (weight, bias) in enumerate(zip(weights, biases, strict=True)):
        if weight.ndim != 2 or weight.shape[1] != inputs or bias.shape != (weight.shape[0],):
            layout = f" ({features} features, history {history})" if i == 0 else ""
            raise ValueError(f"layer {i}: weight {weight.shape} and bias {bias.shape} do not fit "
                             f"{inputs} inputs{layout}")
        inputs = weight.shape[0]
    if inputs != outputs:
        raise ValueError(f"the last layer gives {inputs} outputs, not "
                         f"{'one voltage' if outputs == 1 else f'{outputs} voltages'}")
    arrays = [*weights, *biases, mean, var]
    if not all(np.isfinite(a).all() for a in arrays):
        raise ValueError("weights or statistics are not finite")
    for key in ("voltage_limit", "epsilon", "clip"):
        value = meta[key]
        if not (isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)):
            raise ValueError(f"{key} must be a finite number, got {value!r}")
    if not (meta["voltage_limit"] > 0 and meta["epsilon"] >= 0 and meta["clip"] > 0):
        raise ValueError("voltage_limit and clip must be positive, epsilon non-negative")
    if np.any(var + meta["epsilon"] <= 0):
        raise ValueError("a variance is 0 and epsilon is 0: that feature's normalisation divides by zero")
