"""`python -m qube_suite` runs the `qube-suite` command line."""

import sys

from qube_suite.cli import main

sys.exit(main())
