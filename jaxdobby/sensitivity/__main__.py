"""``python -m jaxdobby.sensitivity``: the ``jaxdobby sobol`` command."""

import sys

from .command import main

sys.exit(main())
