"""Command line of the memory package, mounted by dms.cli."""

import typer

app = typer.Typer(no_args_is_help=True)

db_app = typer.Typer(no_args_is_help=True)
