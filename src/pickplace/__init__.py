"""pickplace: closed-loop pick and place with a simulated UR5e in MuJoCo."""

import logging

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())
