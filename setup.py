"""Build the compiled parts of qube_suite: the Cython HIL board substitute and the iLQR kernel.

Everything else about the package is declared in pyproject.toml.
"""

from Cython.Build import cythonize
from setuptools import Extension, setup

setup(
    ext_modules=cythonize(
        [Extension("qube_suite.hardware._hil_sim", ["qube_suite/hardware/_hil_sim.pyx"]),
         Extension("qube_suite.devices.qube.controllers._ilqr",
                   ["qube_suite/devices/qube/controllers/_ilqr.pyx"])],
        compiler_directives={"language_level": "3"},
    ),
)
