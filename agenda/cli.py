"""Command line of the agenda package, mounted by dms.cli."""

import typer

app = typer.Typer(no_args_is_help=True)
