"""``dms record``: record a robot's key space into MCAP, describe a recording, play one back.

Mounted by dms.cli as ``dms record`` (``dms record``, ``dms record info FILE``, ``dms record
play FILE``), as ``ros2 bag record|info|play`` are.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated, Any

import typer

from dms.kernel.cli_options import (
    DEFAULT_ENDPOINT,
    ConnectOption,
    RobotOption,
    ZenohConfigOption,
)
from sim.errors import SimError

if TYPE_CHECKING:
    from dms.bus import ZenohClient
    from sim.recording import McapRecorder


def _stop_on_signals() -> threading.Event:
    """An event set by SIGINT or SIGTERM (the way to end a live command)."""
    stop = threading.Event()

    def handler(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


def default_name(robot_id: str, now: datetime) -> Path:
    """``dms_<robot>_<YYYYmmdd-HHMMSS>.mcap`` in the current folder (as ros2 bag names one)."""
    return Path(f"dms_{robot_id}_{now:%Y%m%d-%H%M%S}.mcap")


record_app = typer.Typer()


@record_app.callback(invoke_without_command=True)
def record_command(
    ctx: typer.Context,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", help="The MCAP file to write.", show_default="dms_<robot>_<time>.mcap here"
        ),
    ] = None,
    only: Annotated[
        list[str] | None,
        typer.Option(
            "--key",
            help="Record only this key (dms/state, /robots/mini/perception/*); repeat for more.",
            show_default="every key under the robot",
        ),
    ] = None,
    robot_id: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    duration: Annotated[
        float | None,
        typer.Option(
            min=0.0, help="Stop after S seconds (else on SIGINT/SIGTERM).", show_default=False
        ),
    ] = None,
) -> None:
    """Record every message under robots/<id>/** into MCAP; dms record info FILE describes
    one, dms record play FILE plays it back.

    JSON with its schemas (for Foxglove) in zstd chunks, with the daemon's seed, settings
    and files, so that dms sim replay FILE needs no flags. Exit 1 when nothing was recorded.
    """
    if ctx.invoked_subcommand is not None:
        return
    import time

    from dms.bus import ZenohClient, make_config
    from dms.kernel.keys import ROBOT_ID_RE
    from dms.operator_cli import absolute_key
    from sim.recording import McapRecorder, record_until

    if not ROBOT_ID_RE.fullmatch(robot_id):
        raise SimError(f"--robot: {robot_id!r} does not match [a-z0-9_-]+")
    exprs = [absolute_key(robot_id, k) for k in only or ["**"]]
    out = out if out is not None else default_name(robot_id, datetime.now())
    endpoints = list(connect or ([] if zenoh_config else [DEFAULT_ENDPOINT]))
    config = make_config(connect=endpoints, config_file=zenoh_config)  # a bad file: one line
    recorder = McapRecorder(out, robot_id)  # a bad --out fails before the network is touched
    started = time.monotonic()
    try:
        stop = _stop_on_signals()
        with ZenohClient(robot_id, config) as client:
            what = ", ".join(exprs)
            print(f"dms: recording {what} into {out}; Ctrl-C stops", file=sys.stderr, flush=True)
            asked = threading.Event()
            fetcher = threading.Thread(
                target=_store_config, args=(client, recorder, stop, asked), daemon=True
            )

            def subscribe(key_expr: str, handler: Callable[[str, bytes], None]) -> None:
                client.subscribe_raw(key_expr, handler)
                if fetcher.ident is None:  # asked after subscribing: it comes on a live link
                    fetcher.start()

            stats = record_until(recorder, subscribe, time.time_ns, stop, duration, exprs)
            asked.set()  # the recording is closed: stop asking
    finally:
        recorder.close()
    where = ", ".join(endpoints) or f"the endpoints of {zenoh_config}"
    if stats.messages == 0:
        out.unlink(missing_ok=True)
        raise SimError(
            f"recorded nothing from {', '.join(exprs)} in {time.monotonic() - started:.1f} s"
            f" (is its daemon running and reachable at {where}?); {out} not kept"
        )
    by_key = ", ".join(f"{key} {count}" for key, count in sorted(stats.by_key.items()))
    stored = "" if stats.configured else "; the daemon's configuration was not stored"
    print(f"dms: {stats.messages} messages recorded ({by_key}){stored}", file=sys.stderr)


def _store_config(
    client: ZenohClient, recorder: McapRecorder, stop: threading.Event, done: threading.Event
) -> None:
    """Once the daemon is alive, ask it for ``dms/config`` and store its answer (the seed,
    settings and files a replay needs); a daemon that does not answer leaves it out."""
    import time

    from dms.daemon import CONFIG_KEY
    from dms.kernel.keys import ALIVE_DMS

    while not (stop.is_set() or done.is_set()):
        if not client.wait_alive(ALIVE_DMS, 0.5):
            continue
        try:
            replies = client.query(CONFIG_KEY, timeout_s=10.0)
        except Exception:  # the session closed under the query: the recording has ended
            return
        for ok, body in replies:
            if ok and isinstance(body, dict) and recorder.add_config(body, time.time_ns()):
                files = body.get("files") or []
                print(
                    f"dms: stored robot {recorder.robot_id}'s configuration for replay "
                    f"(seed {body.get('seed')}, {len(files)} files)",
                    file=sys.stderr,
                    flush=True,
                )
                return
        return


@record_app.command("info")
def record_info_command(
    file: Annotated[Path, typer.Argument(help="An MCAP file written by dms record.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the description as JSON.")] = False,
) -> None:
    """Describe a recording, as ros2 bag info does.

    Its duration, messages per topic, chunks and their compression, and the daemon's
    configuration stored for replay.
    """
    from sim.recording import recording_info

    info = recording_info(file)
    for warning in (info.get("config") or {}).get("warnings", []):
        print(f"dms: {file}: {warning}", file=sys.stderr)
    if as_json:
        typer.echo(json.dumps(info, indent=2))
        return
    typer.echo(_info_text(info))


def _info_text(info: dict[str, Any]) -> str:
    from datetime import UTC, datetime

    def when(ns: int | None) -> str:
        if ns is None:
            return "-"
        return datetime.fromtimestamp(ns / 1e9, UTC).isoformat(timespec="milliseconds")

    start, end = info.get("start_ns"), info.get("end_ns")
    duration = (end - start) / 1e9 if start is not None and end is not None else 0.0
    lines = [
        f"File:          {info['file']}",
        f"Size:          {_size(info['bytes'])}",
        f"Duration:      {duration:.3f} s",
        f"Start:         {when(start)}",
        f"End:           {when(end)}",
        f"Messages:      {info['messages']}",
    ]
    if info.get("complete"):
        ratio = info["uncompressed_bytes"] / max(1, info["compressed_bytes"])
        lines.append(
            f"Chunks:        {info['chunks']} ({', '.join(info['compression']) or 'none'}; "
            f"{_size(info['uncompressed_bytes'])} -> {_size(info['compressed_bytes'])}, "
            f"{ratio:.1f}x)"
        )
    else:
        lines.append(f"Truncated:     {info.get('truncated')}")
    config = info.get("config")
    if config is None:
        lines.append("Configuration: not stored (dms sim replay needs --config and --seed)")
    else:
        versions = ", ".join(f"{k} {v}" for k, v in config["versions"].items())
        lines.append(f"Robot:         {config['robot_id']}")
        lines.append(f"Seed:          {config['seed'] if config['seed'] is not None else 'none'}")
        lines.append(f"Versions:      {versions}")
        files = config["files"]
        groups: dict[str, int] = {}
        for name in files:
            groups[name.split("/", 1)[0]] = groups.get(name.split("/", 1)[0], 0) + 1
        rules = [name.split("/")[-1] for name in files if name.startswith("rules/")]
        shown = ", ".join(f"{group} {count}" for group, count in sorted(groups.items()))
        lines.append(f"Files stored:  {len(files)} ({shown or 'none'})")
        if rules:
            lines.append(f"Rules:         {', '.join(rules)}")
    topics = info["topics"]
    width = max((len(t["topic"]) for t in topics), default=0)
    lines.append("Topics:" if topics else "Topics:        none")
    for topic in topics:
        schema = topic["schema"] or "-"
        lines.append(f"  {topic['topic']:<{width}}  {topic['count']:>7}  {schema}")
    return "\n".join(lines)


def _size(count: int) -> str:
    value = float(count)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if value < 1024 or unit == "GiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1024
    return f"{count} B"


@record_app.command("play")
def record_play_command(
    file: Annotated[Path, typer.Argument(help="An MCAP file written by dms record.")],
    rate: Annotated[
        float, typer.Option(min=0.01, help="Play this many times faster than recorded.")
    ] = 1.0,
    loop: Annotated[bool, typer.Option("--loop", help="Start again after the last message.")] = (
        False
    ),
    robot_id: Annotated[
        str | None,
        typer.Option(
            "--robot", "--robot-id", help="Publish under this robot.", show_default="the recorded"
        ),
    ] = None,
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """Publish a recording back onto the bus at its recorded pace, as ros2 bag play does.

    Every message goes on robots/<id>/<key> as it was recorded, outputs (dms/state,
    dms/decision) included: play inputs to a daemon only when no other source sends them.
    Stops after the last message (or, with --loop, on SIGINT/SIGTERM).
    """
    from dms.bus import ZenohClient, make_config
    from dms.kernel.keys import ROBOT_ID_RE
    from sim.recording import RecordedMessage, RecordingReader, play, recording_info

    # Described first, from its summary when it is complete (or read through once when it
    # is not): a file over a bound is refused before the bus is touched.
    info = recording_info(file)
    if not info.get("complete"):
        print(f"dms: {file}: truncated: {info.get('truncated')}", file=sys.stderr)
    for warning in (info.get("config") or {}).get("warnings", []):
        print(f"dms: {file}: {warning}", file=sys.stderr)
    recorded = next(
        (t["topic"].split("/")[1] for t in info["topics"] if t["topic"].startswith("robots/")),
        None,
    )
    robot = robot_id or (recorded if recorded != "?" else None) or "mini"
    if not ROBOT_ID_RE.fullmatch(robot):
        raise SimError(f"--robot: {robot!r} does not match [a-z0-9_-]+")
    if not info["messages"]:
        raise SimError(f"{file}: no message to play")
    endpoints = list(connect or ([] if zenoh_config else [DEFAULT_ENDPOINT]))
    config = make_config(connect=endpoints, config_file=zenoh_config)
    stop = _stop_on_signals()
    span = ((info["end_ns"] or 0) - (info["start_ns"] or 0)) / 1e9
    with ZenohClient(robot, config) as client:

        def publish(message: RecordedMessage) -> None:
            client.publish(message.key, message.payload)

        print(
            f"dms: playing {info['messages']} messages ({span:.1f} s at {rate:g}x) "
            f"from {file} onto robots/{robot}/; Ctrl-C stops",
            file=sys.stderr,
            flush=True,
        )
        reader = RecordingReader(file, keep_attachments=False)
        published = play(reader.messages, publish, stop, rate=rate, loop=loop)
    print(f"dms: {published} messages played", file=sys.stderr)


__all__ = ["record_app", "record_command"]
