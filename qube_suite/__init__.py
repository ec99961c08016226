"""qube_suite: control and reinforcement-learning tasks on the Quanser Qube-Servo 2.

    from qube_suite import suite
    env = suite.load("qube", "swingup")              # dm_env

    import gymnasium, qube_suite
    env = gymnasium.make("QubeSuite/Swingup-v0")     # Gymnasium
"""

from qube_suite import headless

headless.choose_backend()  # before MuJoCo and dm_control are imported

from qube_suite.evaluation import evaluate  # noqa: E402
from qube_suite.wrappers import register_environments, to_gymnasium  # noqa: E402

__version__ = "0.1.0"

register_environments()

__all__ = ["__version__", "evaluate", "to_gymnasium"]
