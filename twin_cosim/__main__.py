"""``python -m twin_cosim`` runs the ``twin`` command line."""

from twin_cosim.cli import run

run()
