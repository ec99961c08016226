"""Build the compiled part of qube_suite: the Cython HIL board substitute.

Everything else about the package is declared in pyproject.toml.
"""

from Cython.Build import cythonize
from setuptools import Extension, setup

setup(
    ext_modules=cythonize(
        [Extension("qube_suite.hardware._hil_sim", ["qube_suite/hardware/_hil_sim.pyx"])],
        compiler_directives={"language_level": "3"},
    ),
)
