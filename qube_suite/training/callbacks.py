"""stable-baselines3 callbacks of `qube-suite train` (imports stable-baselines3)."""

from __future__ import annotations

from collections.abc import Callable

from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from qube_suite.progress import Progress


class ProgressBar(BaseCallback):
    """Progress in environment steps (`qube_suite.progress`: a bar on a terminal, a line per 10 %
    otherwise), showing the latest evaluation's mean return."""

    def __init__(self, total_steps: int, evaluation: EvalCallback | None = None):
        super().__init__()
        self._total = total_steps
        self._evaluation = evaluation
        self._bar: Progress | None = None

    def _on_training_start(self) -> None:
        self._bar = Progress(self._total, "step", "training")

    def _on_step(self) -> bool:
        if self._evaluation is not None and self._evaluation.evaluations_results:
            self._bar.set_postfix(eval_return=f"{self._evaluation.last_mean_reward:.0f}")
        self._bar.advance_to(self.num_timesteps)
        return True

    def _on_training_end(self) -> None:
        self._bar.close()


class OnNewBest(BaseCallback):
    """Calls `action()` when the parent `EvalCallback` finds a new best mean return."""

    def __init__(self, action: Callable[[], None]):
        super().__init__()
        self._action = action

    def _on_step(self) -> bool:
        self._action()
        return True


class FrozenUntil(BaseCallback):
    """Keeps `parameters` frozen (no gradient) until `steps` environment steps, then frees them."""

    def __init__(self, parameters: list, steps: int):
        super().__init__()
        self._parameters = parameters
        self._steps = steps

    def _on_training_start(self) -> None:
        self._set(self.num_timesteps >= self._steps)

    def _on_rollout_start(self) -> None:
        self._set(self.num_timesteps >= self._steps)

    def _on_step(self) -> bool:
        return True

    def _set(self, free: bool) -> None:
        for parameter in self._parameters:
            parameter.requires_grad_(free)
