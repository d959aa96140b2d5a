"""Command line of the sim package, mounted by dms.cli."""

import typer

app = typer.Typer(no_args_is_help=True)


def record_command() -> None:
    """Record every message of one robot into MCAP."""
    raise typer.Exit(1)
