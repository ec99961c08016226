"""Step speed of qube_suite against Gymnasium, dm_control and raw MuJoCo, all measured in one run.

    python benchmarks/step_speed.py           # about 2 minutes
    python benchmarks/step_speed.py --quick   # a few seconds, rough

Prints one table (the same as `qube-suite bench`); the rows are listed in
`qube_suite.benchmark.measurements`.
"""

import argparse
import sys

from qube_suite import benchmark

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short rounds and fewer batch sizes")
    sys.exit(benchmark.main(quick=parser.parse_args().quick))
