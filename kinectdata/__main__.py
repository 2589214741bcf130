"""``python -m kinectdata`` runs the command line."""

from kinectdata.cli import main

main()
