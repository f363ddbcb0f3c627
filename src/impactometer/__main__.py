"""``python -m impactometer``: the command line."""

from impactometer.cli import main

main()
