"""``python -m dms_ros2``: run the ``dms_bridge`` node until SIGINT or SIGTERM.

``dms ros2`` runs this in the bridge's own environment. By default the node configures
and activates itself; ``--unconfigured`` leaves that to a lifecycle manager (a launch
file, ``ros2 lifecycle set``). Arguments after ``--ros-args`` are ROS 2's own.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

DEFAULT_CONNECT = "tcp/127.0.0.1:7447"


def parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="dms ros2", description="Bridge one robot's dms keys to ROS 2 and back."
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
    parser.add_argument(
        "--unconfigured",
        action="store_true",
        help="wait for a lifecycle manager to configure and activate the node",
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.utilities import remove_ros_args

    from dms_ros2 import topics
    from dms_ros2.bridge import Bridge

    full = sys.argv if argv is None else ["dms_ros2", *argv]
    args = parse(remove_ros_args(full)[1:])
    if not topics.ROBOT_ID_RE.match(args.robot):
        print(
            f"dms ros2: --robot {args.robot!r}: lower-case letters, digits, _ and -",
            file=sys.stderr,
        )
        return 2
    connect = args.connect or ([] if args.zenoh_config else [DEFAULT_CONNECT])
    rclpy.init(args=full)
    bridge = Bridge(args.robot, connect, args.zenoh_config)
    try:
        if not args.unconfigured:
            if bridge.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                print("dms ros2: the node could not be configured (see above)", file=sys.stderr)
                return 1
            bridge.trigger_activate()
        executor = SingleThreadedExecutor()
        executor.add_node(bridge)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for step in (bridge.close_zenoh, bridge.destroy_node, rclpy.try_shutdown):
            try:
                step()
            except Exception as error:  # a stop that was asked for stays a clean stop
                print(f"dms ros2: while stopping: {type(error).__name__}: {error}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    # Fast DDS's and Zenoh's native threads outlive the node; once it has stopped cleanly,
    # the interpreter's own teardown of them once turned a SIGTERM into exit 1 in CI.
    os._exit(code)
