"""``python -m dms_reachy``: drive a Reachy Mini as one dms robot until SIGINT or SIGTERM.

``dms reachy`` runs this in the bridge's own environment (``.venv-reachy``). The Zenoh
session is a client of the daemon (one endpoint) or a peer of several, listening
nowhere, with multicast scouting off; it fails after 5 s when no endpoint answers.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

DEFAULT_CONNECT = "tcp/127.0.0.1:7447"
CONNECT_TIMEOUT_S = 5.0


def parse(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="dms reachy", description="Drive a Reachy Mini as one dms robot."
    )
    parser.add_argument("--robot", "--robot-id", dest="robot", default="mini", help="robot id")
    parser.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"Zenoh endpoint of the daemon or a router (default {DEFAULT_CONNECT})",
    )
    parser.add_argument("--zenoh-config", type=Path, help="Zenoh JSON5 configuration file")
    parser.add_argument("--host", default="localhost", help="Reachy Mini daemon's host")
    parser.add_argument("--port", type=int, default=8000, help="Reachy Mini daemon's port")
    parser.add_argument(
        "--media",
        action="store_true",
        help="use the robot's speaker (speech through espeak-ng); off: speech is printed",
    )
    parser.add_argument(
        "--faces",
        action="store_true",
        help="publish the face the robot's camera tracks as perception/user (off: a "
        "perception module publishes it)",
    )
    return parser.parse_args(list(argv))


def zenoh_config(connect: Sequence[str], config_file: Path | None) -> object:
    import zenoh

    config = zenoh.Config.from_file(str(config_file)) if config_file else zenoh.Config()
    if config_file is None:
        config.insert_json5("mode", json.dumps("client" if len(connect) == 1 else "peer"))
        config.insert_json5("listen/endpoints", "[]")
    if connect:
        config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("connect/exit_on_failure", "true")
    config.insert_json5("connect/timeout_ms", str(int(CONNECT_TIMEOUT_S * 1000)))
    return config


def main(argv: Sequence[str] | None = None) -> int:
    stop = threading.Event()

    def ask_to_stop(signum: int, frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGINT, ask_to_stop)
    signal.signal(signal.SIGTERM, ask_to_stop)
    args = parse(sys.argv[1:] if argv is None else argv)

    from dms_reachy.commands import ROBOT_ID_RE

    if not ROBOT_ID_RE.match(args.robot):
        print(
            f"dms reachy: --robot {args.robot!r}: lower-case letters, digits, _ and -",
            file=sys.stderr,
        )
        return 2
    if not 0 < args.port < 65536:
        print(f"dms reachy: --port {args.port}: a TCP port, 1 to 65535", file=sys.stderr)
        return 2

    import zenoh

    from dms_reachy.bridge import Bridge, log
    from dms_reachy.robot import Reachy

    connect = args.connect or ([] if args.zenoh_config else [DEFAULT_CONNECT])
    try:
        session = zenoh.open(zenoh_config(connect, args.zenoh_config))  # type: ignore[arg-type]
    except (zenoh.ZError, ValueError, OSError) as error:
        reason = " ".join(str(error).split())
        print(
            f"dms reachy: cannot reach the daemon over Zenoh {connect}: {reason}", file=sys.stderr
        )
        return 1
    reachy = Reachy(args.host, args.port, media=args.media)
    bridge = Bridge(args.robot, session, reachy, publish_faces=args.faces)
    try:
        bridge.listen()
        where = f"{args.host}:{args.port}"
        log(f"robot {args.robot} over Zenoh {connect or '(file)'}; Reachy Mini at {where}")
        bridge.run(stop)
    finally:
        bridge.reachy.close()
        session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
