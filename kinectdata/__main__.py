"""``python -m kinectdata`` runs the command line."""

from .cli import main

main()
