"""Planning benchmark: pickplace's RRT* against OMPL's RRTConnect and RRT*, side by side in one run.

Run ``make bench`` (installs the ``bench`` extra with OMPL) or ``pickplace bench planning [--json]``.
The implementation lives in :mod:`pickplace.bench.planning`.
"""

import sys

from pickplace.bench.planning import main

if __name__ == "__main__":
    sys.exit(main())
