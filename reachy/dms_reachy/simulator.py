"""``python -m dms_reachy.simulator --port P``: the maker's simulated Reachy Mini, kept
to this machine.

It is ``reachy-mini-daemon --sim --headless --no-media --fastapi-port P`` (MuJoCo, no
display, ``MUJOCO_GL=disable``), with what would reach the network turned off: the mDNS
advertisement of the robot (the daemon has no flag for it), the anonymous telemetry
(``DO_NOT_TRACK``) and the hourly check for new datasets. The tests and the benchmark
start it on a port of their own; ``--mockup-sim`` gives the SDK's robot without physics.
"""

from __future__ import annotations

import argparse
import os
import sys


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m dms_reachy.simulator")
    parser.add_argument("--port", type=int, required=True, help="the daemon's HTTP port")
    parser.add_argument("--mockup-sim", action="store_true", help="no physics (no MuJoCo)")
    args = parser.parse_args()
    os.environ["MUJOCO_GL"] = "disable"
    os.environ["DO_NOT_TRACK"] = "1"
    os.environ["REACHY_MINI_TELEMETRY"] = "0"

    from reachy_mini.daemon.app import main as daemon_main
    from reachy_mini.utils import discovery

    def no_advertisement(self: object) -> None:
        """The robot is not announced by mDNS: the test's clients know its port."""

    discovery.MdnsServiceRegistration.register = no_advertisement
    sys.argv = [
        "reachy-mini-daemon",
        "--mockup-sim" if args.mockup_sim else "--sim",
        "--headless",
        "--no-media",
        "--fastapi-host",
        "127.0.0.1",
        "--fastapi-port",
        str(args.port),
        "--dataset-update-interval",
        "0",
        "--log-level",
        "INFO",  # its "Application startup complete" says it serves
    ]
    daemon_main.main()
    return 0


if __name__ == "__main__":
    sys.exit(main())
