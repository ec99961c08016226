"""Domain randomization and simulator-accuracy effects for the Qube.

    from qube_suite import randomization, suite
    env = suite.load("qube", "balance", randomization="sim2real")           # a preset
    env = suite.load("qube", "balance", randomization="my_config.yaml")     # a YAML file
    env = suite.load("qube", "balance", randomization={"effects": {"action_delay": {"steps": 2}}})

A config (`config.py`) gives physical parameters by long name, each with a
distribution (`distributions.py`), and sensor and actuator effects by name
(`catalog.EFFECTS`), each on the effect interface of `base.py`. Every reset
draws new values from the task's random state (`sampling.py`) and applies them
to the domain (`randomizer.py`).
"""

from qube_suite.randomization.amplifier import DeadZone, Saturation, VoltageOffset
from qube_suite.randomization.base import Chain, Effect, Field, Streams
from qube_suite.randomization.catalog import EFFECTS
from qube_suite.randomization.config import Randomization, load, parse
from qube_suite.randomization.delays import ActionDelay, ObservationDelay
from qube_suite.randomization.distributions import Distribution
from qube_suite.randomization.presets import PRESETS
from qube_suite.randomization.randomizer import OneQube, Randomizer
from qube_suite.randomization.sampling import Sample, sample, sample_effects, sample_parameters
from qube_suite.randomization.sensors import FilteredVelocity, ObservationNoise, Quantization
from qube_suite.randomization.timing import ControlJitter

__all__ = [
    "EFFECTS", "PRESETS", "ActionDelay", "Chain", "ControlJitter", "DeadZone", "Distribution", "Effect",
    "Field", "FilteredVelocity", "ObservationDelay", "ObservationNoise", "OneQube", "Quantization",
    "Randomization", "Randomizer", "Sample", "Saturation", "Streams", "VoltageOffset",
    "load", "parse", "sample", "sample_effects", "sample_parameters",
]
