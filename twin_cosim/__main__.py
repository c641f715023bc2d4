"""``python -m twin_cosim`` runs the ``twin`` command line."""

import sys

from twin_cosim.cli import main

sys.exit(main())
