"""``python -m actionreasoning`` runs the command-line tool."""

from actionreasoning.cli import app

app(prog_name="actionreasoning")
