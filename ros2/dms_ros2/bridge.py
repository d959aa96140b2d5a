"""The ``dms_bridge`` node: one robot's Zenoh keys as ROS 2 topics, and back.

A managed (lifecycle) node. ``configure`` opens the Zenoh session and makes the ROS 2
publishers and subscriptions; ``activate`` starts carrying messages and the 1 Hz
diagnostics; ``deactivate`` stops both (messages meanwhile are dropped, not queued);
``cleanup`` closes the Zenoh session. What it carries is :mod:`dms_ros2.topics`.

Zenoh callbacks run on Zenoh's threads and publish to ROS 2 from there (rcl's publish
is thread-safe); the ROS 2 side runs on the node's executor. The ROS 2 discovery
settings (``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``...) are the
environment's: nothing here sets them.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import zenoh
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from dms_ros2 import convert, topics
from dms_ros2.topics import Qos

NODE_NAME = "dms_bridge"
AS_STRING = ("dms/state", "dms/decision", "dms/errors", "robot/command")
"""Keys published on the ROS 2 topic of the same name as their JSON, unchanged."""
ZENOH_KEYS = (*AS_STRING, "robot/joints", "perception/user", "perception/objects")
"""Every key the bridge listens to (perception/user with the bridge's own puts: the
face it merges in is then drawn too)."""
CONNECT_TIMEOUT_S = 5.0
DIAGNOSTICS_PERIOD_S = 1.0

QOS = {
    Qos.EVENTS: QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=50,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    ),
    Qos.LATCHED: QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    ),
    Qos.SENSOR: QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
        reliability=ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.VOLATILE,
    ),
    Qos.DIAGNOSTICS: QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    ),
}


def zenoh_config(connect: Sequence[str], config_file: Path | None) -> zenoh.Config:
    """A client of the daemon (one endpoint) or a peer of several, listening nowhere,
    multicast scouting off, failing when no endpoint answers within 5 s; a file's
    settings win over the endpoints' defaults. Once open, a lost link is retried."""
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


class Bridge(LifecycleNode):
    """The bridge for ``robot_id``, in the namespace ``/robots/<robot_id>``."""

    def __init__(
        self, robot_id: str, connect: Sequence[str], config_file: Path | None = None
    ) -> None:
        super().__init__(NODE_NAME, namespace=topics.ros_namespace(robot_id))
        self.robot_id = robot_id
        self.connect = list(connect)
        self.config_file = config_file
        self.frame_id = str(self.declare_parameter("frame_id", "base").value)
        self._session: zenoh.Session | None = None
        self._zenoh_handles: list[Any] = []
        self._robot_token: Any = None
        self._ins: list[Any] = []
        self._outs: dict[str, Any] = {}
        self._timer: Any = None
        self._active = threading.Event()
        self._lock = threading.Lock()
        self._state: dict[str, Any] | None = None
        self._state_at: float | None = None
        self._alive = False
        self._last_user: dict[str, Any] | None = None
        self._frames = convert.Frames(self.frame_id)
        self.failure: str | None = None
        """Why the last configure failed, in one line; None when it did not."""

    # -- lifecycle -------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Open the Zenoh session and make every endpoint; log what is bridged. On a
        failure, :attr:`failure` says why: rclpy drops an exception raised here, and
        the ROS log may go where nobody reads it."""
        self.failure = None
        try:
            self._session = zenoh.open(zenoh_config(self.connect, self.config_file))
        except (zenoh.ZError, ValueError, OSError) as error:
            return self._failed(f"cannot open the Zenoh session: {' '.join(str(error).split())}")
        try:
            self._make_ros_endpoints()
            self._make_zenoh_endpoints(self._session)
        except Exception as error:  # rclpy would turn it into ERROR without a word
            self.close_zenoh()
            reason = " ".join(str(error).split())
            return self._failed(f"cannot make its endpoints: {type(error).__name__}: {reason}")
        logger = self.get_logger()
        logger.info(f"bridging robot {self.robot_id} over Zenoh {self.connect or '(file)'}:")
        for line in topics.table(self.robot_id):
            logger.info(f"  {line}")
        return TransitionCallbackReturn.SUCCESS

    def _failed(self, reason: str) -> TransitionCallbackReturn:
        self.failure = reason
        self.get_logger().error(reason)
        return TransitionCallbackReturn.FAILURE

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._active.set()
        self._timer = self.create_timer(DIAGNOSTICS_PERIOD_S, self._every_second)
        self.get_logger().info("active: carrying messages")
        result: TransitionCallbackReturn = super().on_activate(state)
        with self._lock:  # the latest state at once, for a late subscriber (latched)
            latest = self._state
        if latest is not None:
            self._publish_string("dms/state", json.dumps(latest))
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._active.clear()
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        self.get_logger().info("inactive: messages are dropped until activated")
        result: TransitionCallbackReturn = super().on_deactivate(state)
        return result

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.close_zenoh()
        for subscription in self._ins:
            self.destroy_subscription(subscription)
        self._ins.clear()
        for publisher in self._outs.values():
            self.destroy_lifecycle_publisher(publisher)
        self._outs.clear()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.close_zenoh()
        return TransitionCallbackReturn.SUCCESS

    def close_zenoh(self) -> None:
        """Stop carrying and close the Zenoh session (its tokens go with it); safe to
        call twice, and after ROS 2 itself was shut down."""
        self._active.clear()
        for handle in self._zenoh_handles:
            handle.undeclare()
        self._zenoh_handles.clear()
        if self._robot_token is not None:
            self._robot_token.undeclare()
            self._robot_token = None
        if self._session is not None:
            self._session.close()
            self._session = None

    # -- endpoints -------------------------------------------------------------------

    def _make_ros_endpoints(self) -> None:
        types = {
            topics.STRING: String,
            "sensor_msgs/msg/JointState": JointState,
            "visualization_msgs/msg/MarkerArray": MarkerArray,
            "diagnostic_msgs/msg/DiagnosticArray": DiagnosticArray,
        }
        for route in topics.OUT_ROUTES:
            self._outs[route.topic] = self.create_lifecycle_publisher(
                types[route.ros_type], route.topic, QOS[route.qos]
            )
        for route in topics.IN_ROUTES:
            if route.topic == topics.FACE_TOPIC:
                callback: Callable[[Any], None] = self._on_face
                kind: Any = PoseStamped
            else:
                callback, kind = self._forwarder(route.key), String
            self._ins.append(self.create_subscription(kind, route.topic, callback, QOS[route.qos]))

    def _make_zenoh_endpoints(self, session: zenoh.Session) -> None:
        prefix = f"robots/{self.robot_id}/"
        for key in ZENOH_KEYS:
            self._zenoh_handles.append(session.declare_subscriber(prefix + key, self._on_zenoh))
        self._zenoh_handles.append(
            session.liveliness().declare_subscriber(
                prefix + "alive/dms", self._on_alive, history=True
            )
        )

    # -- Zenoh to ROS 2 --------------------------------------------------------------

    def _on_alive(self, sample: zenoh.Sample) -> None:
        self._alive = sample.kind == zenoh.SampleKind.PUT

    def _on_zenoh(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)[len(f"robots/{self.robot_id}/") :]
        text = sample.payload.to_string()
        try:
            payload = json.loads(text)
        except ValueError:
            payload = None
        now = time.time()
        if key == "dms/state" and isinstance(payload, dict):
            with self._lock:
                self._state, self._state_at = payload, time.monotonic()
        if not self._active.is_set():
            return
        if key in AS_STRING:
            self._publish_string(key, text)
        if not isinstance(payload, dict):
            return
        if key == "robot/joints":
            joints = convert.joint_state(payload, now)
            if joints is not None:
                self._outs["joint_states"].publish(joints)
        elif key in ("perception/user", "perception/objects", "robot/command"):
            with self._lock:
                if key == "perception/user":
                    self._frames.on_user(payload, now)
                    self._last_user = payload  # what a face from ROS 2 is merged into
                elif key == "perception/objects":
                    self._frames.on_objects(payload, now)
                elif payload.get("channel") != "aim":
                    return
                else:
                    self._frames.on_command(payload)
                markers = self._frames.markers(now)
            self._outs["dms/frames"].publish(markers)

    def _publish_string(self, topic: str, text: str) -> None:
        publisher = self._outs.get(topic)
        if publisher is not None:
            publisher.publish(String(data=text))

    def _every_second(self) -> None:
        """The diagnostics, the markers' ages, and the robot's token: a ROS 2 node
        publishing ``robot/feedback`` is a robot there, as ``alive/robot/feedback``
        says on Zenoh (the daemon then knows it without waiting for a message)."""
        now = time.time()
        with self._lock:
            state = self._state
            age = None if self._state_at is None else time.monotonic() - self._state_at
            markers = self._frames.markers(now)
        self._outs["/diagnostics"].publish(
            convert.diagnostics(self.robot_id, state, age, self._alive, now)
        )
        self._outs["dms/frames"].publish(markers)
        robot_there = self.count_publishers("robot/feedback") > 0
        session = self._session
        if session is None:
            return
        if robot_there and self._robot_token is None:
            token_key = f"robots/{self.robot_id}/alive/robot/feedback"
            self._robot_token = session.liveliness().declare_token(token_key)
        elif not robot_there and self._robot_token is not None:
            self._robot_token.undeclare()
            self._robot_token = None

    # -- ROS 2 to Zenoh --------------------------------------------------------------

    def _forwarder(self, key: str) -> Callable[[Any], None]:
        def forward(message: String) -> None:
            if not self._active.is_set():
                return
            problem = topics.json_object_error(message.data)
            if problem is not None:
                # forwarded all the same: the daemon rejects it, counts it and reports
                # it on dms/errors, as it does a bad message from any other module
                self.get_logger().warning(
                    f"{key}: {problem} (the daemon will reject it)",
                    throttle_duration_sec=1.0,
                )
            elif key == topics.FACE_KEY:
                with self._lock:
                    self._last_user = json.loads(message.data)
            self._put(key, message.data)

        return forward

    def _on_face(self, message: PoseStamped) -> None:
        if not self._active.is_set():
            return
        with self._lock:
            merged = convert.face_into_user(self._last_user, message)
        self._put(topics.FACE_KEY, json.dumps(merged))

    def _put(self, key: str, text: str) -> None:
        session = self._session
        if session is not None:
            session.put(
                f"robots/{self.robot_id}/{key}",
                text.encode(),
                encoding=zenoh.Encoding.APPLICATION_JSON,
            )
