"""``python -m pickplace``: the same as the ``pickplace`` command."""

import sys

from pickplace.cli import main

sys.exit(main())
