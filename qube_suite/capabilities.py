"""What a domain can do beyond the domain interface, declared as protocols and checked with `isinstance`.

Every domain offers the interface tasks use (`qube_suite.domains.interface`); some
offer more, and the code that needs more asks for it here by name instead of probing
for attributes. A domain has a capability by having its members (`typing.Protocol`,
checked at run time): nothing to inherit or register.

| protocol | who has it | who asks |
|---|---|---|
| `Randomizable` | the simulation, one Qube or a batch | the randomizer (physical parameters) |
| `SensorEffects` | simulation, batch, board | the randomizer (effects on the measurement) |
| `ActuatorEffects` | simulation, batch, board, a device's domains | the randomizer (effects on the voltage) |
| `StepDurationEffects` | simulation, batch | the randomizer (control jitter) |
| `Batch` | a batch of simulated Qubes | the randomizer |
| `HasBoard` | the hardware domain | `suite.load` (voltage limit), recorder, media, calibration |
| `NeedsResetControllers` | the hardware domain | `suite.load` |
| `HasDesignParameters` | the hardware domain | `baselines.for_environment` |
| `Closable` | the simulation | `Environment.closed` |
| `NamedState` | a device's domains whose state is not the pendulum's | the recorder (state columns) |
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class Randomizable(Protocol):
    """Physical parameters set by long name, in place (one Qube: `set_parameters(overrides)`; a batch:
    `set_parameters(world, overrides)`)."""

    UNMODELLED_PARAMETERS: frozenset[str]
    """Parameters of the table that this domain does not model: randomizing them changes nothing."""

    def set_parameters(self, *args: Any) -> None: ...


@runtime_checkable
class SensorEffects(Protocol):
    """Measurements through a sensor model (`set_sensor_model(model)`, None: exact)."""

    def set_sensor_model(self, sensor_model: Callable | None) -> None: ...


@runtime_checkable
class ActuatorEffects(Protocol):
    """Voltages through an actuator model (`set_actuator_model(model)`, None: as commanded)."""

    def set_actuator_model(self, actuator_model: Callable | None) -> None: ...


@runtime_checkable
class StepDurationEffects(Protocol):
    """Control periods through a step-duration model (`set_step_duration_model(model)`, None: nominal)."""

    def set_step_duration_model(self, step_duration_model: Callable | None) -> None: ...


@runtime_checkable
class Batch(Protocol):
    """A batch of simulated Qubes ("worlds")."""

    num_worlds: int


@runtime_checkable
class HasBoard(Protocol):
    """A domain driving a Quanser board (the substitute or a real one) through the safe wrapper."""

    qube: Any
    """The board wrapper (`qube_suite.hardware.quanser.QuanserWrapper`)."""

    paced_by_board: bool
    """Whether the board's clock paces every step: nothing slower than a sample may run in the loop."""

    @property
    def max_voltage(self) -> float:
        """The wrapper's voltage clip (V): no task may ask for more."""

    def raw_readings(self) -> dict[str, float]:
        """The last sample's readings in board units, by name."""


@runtime_checkable
class NeedsResetControllers(Protocol):
    """A domain that reaches its episodes' starts with controllers it is handed (domains import none)."""

    reset_controller_names: tuple[str, ...]

    def reset_controller_settings(self) -> dict[str, Any]:
        """Keyword arguments to build each reset controller with (`baselines.make(name, **settings)`)."""

    def set_reset_controllers(self, controllers: Mapping[str, Any]) -> None: ...


@runtime_checkable
class HasDesignParameters(Protocol):
    """A domain whose plant differs from the nominal model in known ways (e.g. another motor)."""

    def design_parameters(self) -> dict[str, float]:
        """Physical parameters by long name that controllers for this plant are designed with."""


@runtime_checkable
class Closable(Protocol):
    """A domain closed for good by `close()`."""

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""


@runtime_checkable
class NamedState(Protocol):
    """A domain whose `qube_state()` is not the pendulum's [theta, alpha, dtheta, dalpha]: it names its
    entries."""

    state_names: tuple[str, ...]
    """The names of `qube_state()`'s entries, in order."""
