"""``python -m printapp`` runs the command line."""

from printapp.cli import main

main()
