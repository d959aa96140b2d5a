"""``dms ros2``: run the ROS 2 bridge (the ``ros2/`` distribution) in its own environment.

The ROS 2 wheels pin lark-parser 0.12, which installs the same ``lark`` module as the
lark 1.x the rule language needs, so the bridge cannot share the daemon's environment.
It gets one of its own, ``.venv-ros2`` beside the checkout (the folder holding
``ros2/``), made with the daemon's Python and pip, and talks to the daemon over Zenoh
only. The environment is made or brought up to date when ``ros2/pyproject.toml`` is
newer than its stamp; then this process becomes the bridge (``exec``).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated

import typer

from dms.bridge_env import become_bridge, check_robot, prepare_environment
from dms.bridge_env import bridge_python as environment_python
from dms.kernel.cli_options import (
    ConnectOption,
    PrepareOption,
    RobotOption,
    ZenohConfigOption,
)

ROS_LIBRARIES = (
    "librcl*.so*",
    "librmw*.so*",
    "librcutils*.so*",
    "librcpputils*.so*",
    "librosidl*.so*",
    "libament_index_cpp*.so*",
    "libfastrtps*.so*",
    "libfastdds*.so*",
    "libfastcdr*.so*",
)
"""Libraries of a ROS 2 (or of its Fast DDS): a folder on ``LD_LIBRARY_PATH`` that holds
one belongs to another ROS, whose versions the bridge's wheels must not load."""
ROS_INSTALLS = ("/opt/ros/",)
"""Where ROS 2 distributions install themselves."""
WHEELS_GUARD = "_ROS_WHEELS_BOOTSTRAP_COMPLETE"
"""The ROS 2 wheels' re-exec guard: set, their bootstrap believes ``LD_LIBRARY_PATH``
already holds their libraries and does nothing."""
FOREIGN_VARIABLES = (
    "AMENT_PREFIX_PATH",
    "COLCON_PREFIX_PATH",
    "CMAKE_PREFIX_PATH",
    "ROS_DISTRO",
    "ROS_VERSION",
    "ROS_PYTHON_VERSION",
    "ROS_PACKAGE_PATH",
)
"""What sourcing another ROS's ``setup.bash`` sets that would point the bridge's client
library at that ROS's packages and type supports. Discovery settings
(``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``, Fast DDS profiles) stay."""

CHECKOUT = Path(__file__).resolve().parents[1]
"""The folder holding ``dms/`` and, in a checkout, ``ros2/``."""
SOURCE = CHECKOUT / "ros2"
VENV = CHECKOUT / ".venv-ros2"


def bridge_python(venv: Path = VENV) -> Path:
    return environment_python(venv)


def prepare(venv: Path = VENV, source: Path = SOURCE, echo: bool = True) -> Path:
    """Make (or bring up to date) the bridge's environment; return its Python
    (:func:`dms.bridge_env.prepare_environment`)."""
    return prepare_environment("ros2", venv, source, echo)


def bridge_environment(environ: Mapping[str, str], venv: Path = VENV) -> dict[str, str]:
    """The environment the bridge runs in: ``environ`` without another ROS 2 in it.

    A process that runs on the ROS 2 wheels passes their guard on, and a shell that
    sourced ``/opt/ros/<distro>/setup.bash`` passes that ROS's library path,
    ``AMENT_PREFIX_PATH`` and Python path: the bridge then loads no libraries, or
    another ROS's, and fails in ways that name neither. So the wheels' libraries are put
    first on the library path (what their bootstrap does, in a fixed order), the guard
    is set so that it does not run again, and another ROS's entries and variables are
    left out; everything else passes as it is."""
    env = {name: value for name, value in environ.items() if name not in FOREIGN_VARIABLES}
    site = (
        venv / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    )
    ours = [str(venv / "lib"), *(str(path) for path in sorted(site.glob("ros_*.libs")))]
    kept = [
        entry for entry in _entries(environ, "LD_LIBRARY_PATH") if not _foreign_libraries(entry)
    ]
    env["LD_LIBRARY_PATH"] = os.pathsep.join(dict.fromkeys([*ours, *kept]))
    python_path = [entry for entry in _entries(environ, "PYTHONPATH") if not _foreign_python(entry)]
    if python_path:
        env["PYTHONPATH"] = os.pathsep.join(python_path)
    else:
        env.pop("PYTHONPATH", None)
    env[WHEELS_GUARD] = "1"
    return env


def _entries(environ: Mapping[str, str], name: str) -> list[str]:
    return [entry for entry in environ.get(name, "").split(os.pathsep) if entry]


def _under_a_ros_install(entry: str) -> bool:
    return any(entry.startswith(prefix) for prefix in ROS_INSTALLS)


def _foreign_libraries(entry: str) -> bool:
    """Whether the library folder ``entry`` holds another ROS 2's libraries."""
    if _under_a_ros_install(entry):
        return True
    folder = Path(entry)
    try:
        return any(next(folder.glob(pattern), None) is not None for pattern in ROS_LIBRARIES)
    except OSError:  # unreadable: the loader cannot use it either
        return False


def _foreign_python(entry: str) -> bool:
    """Whether the Python path entry ``entry`` holds another ROS 2's client library."""
    if _under_a_ros_install(entry):
        return True
    try:
        return (Path(entry) / "rclpy").is_dir()
    except OSError:
        return False


def ros2(
    robot: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    unconfigured: Annotated[
        bool,
        typer.Option(help="Leave the node for a lifecycle manager to configure and activate."),
    ] = False,
    only_prepare: PrepareOption = False,
) -> None:
    """Bridge a robot's keys to ROS 2 and back (node dms_bridge in /robots/<id>) until
    SIGINT or SIGTERM; the bridge runs in its own environment, .venv-ros2 beside the
    checkout, made on first use (docs/ros2.md)."""
    check_robot(robot)
    python = prepare()
    if only_prepare:
        typer.echo(str(python))
        return
    extra = ["--unconfigured"] if unconfigured else []
    become_bridge(
        python, "dms_ros2", robot, connect, zenoh_config, extra, bridge_environment(os.environ)
    )
