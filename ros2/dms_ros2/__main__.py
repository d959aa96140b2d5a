"""``python -m dms_ros2``: run the ``dms_bridge`` node until SIGINT or SIGTERM.

``dms ros2`` runs this in the bridge's own environment. By default the node configures
and activates itself; ``--unconfigured`` leaves that to a lifecycle manager (a launch
file, ``ros2 lifecycle set``). Arguments after ``--ros-args`` are ROS 2's own.

SIGINT and SIGTERM are this module's, not rclpy's: rclpy's handler wakes the executor and
only then shuts the context down from another thread, so an executor that woke in
between either waits again with nothing left to wake it (a node with no timer, as after
``cleanup``, never exits) or builds its next wait set on a dead context (``RCLError``,
exit 1). Here a signal only sets a flag, the executor spins in slices short enough to
see it, and the node is stopped in order from the main thread, in any lifecycle state.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from pathlib import Path

DEFAULT_CONNECT = "tcp/127.0.0.1:7447"
SPIN_SLICE_S = 0.1
"""The longest the executor waits before it looks at the stop flag again: how late a
SIGTERM is seen at worst."""


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
    stop = threading.Event()

    def ask_to_stop(signum: int, frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGINT, ask_to_stop)
    signal.signal(signal.SIGTERM, ask_to_stop)

    try:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.lifecycle import TransitionCallbackReturn
        from rclpy.signals import SignalHandlerOptions
        from rclpy.utilities import remove_ros_args

        from dms_ros2.bridge import Bridge
    except ImportError as error:  # rclpy's own message spans lines and names no cause
        first = str(error).strip().splitlines()[0] if str(error).strip() else repr(error)
        print(
            f"dms ros2: ROS 2's client library cannot be loaded: {first} (LD_LIBRARY_PATH "
            f"{os.environ.get('LD_LIBRARY_PATH', '(unset)')}; `dms ros2` sets the "
            "environment the bridge needs)",
            file=sys.stderr,
        )
        return 1
    from dms_ros2 import topics

    full = sys.argv if argv is None else ["dms_ros2", *argv]
    args = parse(remove_ros_args(full)[1:])
    if not topics.ROBOT_ID_RE.fullmatch(args.robot):
        print(
            f"dms ros2: --robot {args.robot!r}: lower-case letters, digits, _ and -",
            file=sys.stderr,
        )
        return 2
    connect = args.connect or ([] if args.zenoh_config else [DEFAULT_CONNECT])
    rclpy.init(args=full, signal_handler_options=SignalHandlerOptions.NO)
    bridge = Bridge(args.robot, connect, args.zenoh_config)
    try:
        if not args.unconfigured:
            if bridge.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                why = bridge.failure or "an error in ROS 2 itself, its log says which"
                print(f"dms ros2: the node could not be configured: {why}", file=sys.stderr)
                return 1
            bridge.trigger_activate()
        executor = SingleThreadedExecutor()
        executor.add_node(bridge)
        while not stop.is_set():
            executor.spin_once(timeout_sec=SPIN_SLICE_S)
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
    # Fast DDS's and Zenoh's native threads outlive the node: once it has stopped, leaving
    # without the interpreter's teardown keeps them from delaying or changing the status.
    os._exit(code)
