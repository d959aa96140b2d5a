"""``python -m dms_ros2.probe``: a plain ROS 2 node driven by JSON lines, for tests and
benchmarks that run in an environment without rclpy (the daemon's).

Each line on stdin is an order; each line on stdout an event, every one stamped with
``t``, this machine's monotonic clock (comparable between processes):

- ``{"op": "sub", "topic", "type", "qos"}``: subscribe; each message then comes out as
  ``{"event": "msg", "topic", "msg": {...fields...}, "t"}``.
- ``{"op": "pub", "topic", "type", "qos", "msg": {...fields...}}``: publish once a
  subscriber matches (no message is sent into the void); ``{"event": "published", "topic", "t"}``.
- ``{"op": "robot", "namespace"}``: act as the robot: answer each ``robot/command``
  with ``robot/feedback`` ``started`` then ``done`` (an ``interrupt`` command with
  ``interrupted`` for its target).
- ``{"op": "get_state", "node"}``: ask a managed node its lifecycle state through its
  ``get_state`` service; ``{"event": "state", "node", "state": "unconfigured", "t"}``.
- ``{"op": "change_state", "node", "transition"}``: ask it for a transition by label
  (``configure``, ``activate``, ``deactivate``, ``cleanup``...) through its
  ``change_state`` service; ``{"event": "transition", "node", "transition", "success", "t"}``.
- ``{"op": "quit"}``.

A service is called once it is there, as a message is published once a subscriber is.

``type`` is ``pkg/msg/Name``; ``qos`` is ``events`` (reliable, keep last 50; the
default), ``latched`` (reliable, transient local, keep last 1) or ``sensor`` (best effort).
It prints ``{"event": "ready"}`` first.
"""

from __future__ import annotations

import importlib
import json
import queue
import sys
import threading
import time
from array import array
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

MATCH_TIMEOUT_S = 60.0

Reply = Callable[[Any], dict[str, Any]]
"""Turns a service's response into the event the probe prints."""


def qos_of(name: str) -> QoSProfile:
    if name == "latched":
        return QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    if name == "sensor":
        return QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    return QoSProfile(depth=50)


def type_of(name: str) -> Any:
    package, _, kind = name.rpartition("/")
    return getattr(importlib.import_module(package.replace("/", ".")), kind)


def to_dict(message: Any) -> Any:
    """A ROS 2 message as plain JSON values (bytes as ints, arrays as lists)."""
    if hasattr(message, "get_fields_and_field_types"):
        return {
            name: to_dict(getattr(message, name)) for name in message.get_fields_and_field_types()
        }
    if isinstance(message, bytes):
        return message[0] if len(message) == 1 else list(message)
    if isinstance(message, list | tuple | array):
        return [to_dict(item) for item in message]
    if hasattr(message, "tolist"):  # a numpy array
        return message.tolist()
    return message


def fill(message: Any, values: dict[str, Any]) -> Any:
    """``message`` with the fields of ``values`` set, nested messages filled in place."""
    for name, value in values.items():
        if isinstance(value, dict):
            fill(getattr(message, name), value)
        else:
            setattr(message, name, value)
    return message


def say(event: dict[str, Any]) -> None:
    event["t"] = time.monotonic()
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


class Probe:
    def __init__(self) -> None:
        self.node = Node("dms_probe")
        self.publishers: dict[str, Any] = {}
        self.waiting: list[tuple[float, str, Any]] = []
        self.keep: list[Any] = []
        self.clients: dict[str, Any] = {}
        self.calls: list[tuple[float, str, Any, Reply]] = []
        self.pending: list[tuple[Any, Reply]] = []

    def order(self, order: dict[str, Any]) -> bool:
        op = order.get("op")
        if op == "sub":
            topic = order["topic"]
            self.keep.append(
                self.node.create_subscription(
                    type_of(order["type"]),
                    topic,
                    lambda m, topic=topic: say({"event": "msg", "topic": topic, "msg": to_dict(m)}),
                    qos_of(order.get("qos", "events")),
                )
            )
            say({"event": "subscribed", "topic": topic})
        elif op == "pub":
            kind = type_of(order["type"])
            self.publisher(order["topic"], kind, order.get("qos", "events"))
            message = fill(kind(), order.get("msg", {}))
            self.waiting.append((time.monotonic() + MATCH_TIMEOUT_S, order["topic"], message))
        elif op == "robot":
            self.act_as_robot(order["namespace"])
        elif op == "get_state":
            self.get_state(order["node"])
        elif op == "change_state":
            self.change_state(order["node"], order["transition"])
        elif op == "quit":
            return False
        return True

    def publisher(self, topic: str, kind: Any, qos: str) -> Any:
        if topic not in self.publishers:
            self.publishers[topic] = self.node.create_publisher(kind, topic, qos_of(qos))
        return self.publishers[topic]

    def flush(self) -> None:
        """Publish what waits for a subscriber, in order, once one matches."""
        still: list[tuple[float, str, Any]] = []
        for deadline, topic, message in self.waiting:
            publisher = self.publishers[topic]
            if still or publisher.get_subscription_count() == 0:
                if time.monotonic() > deadline:
                    say({"event": "error", "topic": topic, "error": "no subscriber matched"})
                else:
                    still.append((deadline, topic, message))
                continue
            publisher.publish(message)
            say({"event": "published", "topic": topic})
        self.waiting = still

    def get_state(self, node: str) -> None:
        kind = type_of("lifecycle_msgs/srv/GetState")

        def reply(response: Any) -> dict[str, Any]:
            return {"event": "state", "node": node, "state": response.current_state.label}

        self.call(f"{node}/get_state", kind, kind.Request(), reply)

    def change_state(self, node: str, transition: str) -> None:
        kind = type_of("lifecycle_msgs/srv/ChangeState")
        request = kind.Request()
        request.transition.label = transition

        def reply(response: Any) -> dict[str, Any]:
            return {
                "event": "transition",
                "node": node,
                "transition": transition,
                "success": response.success,
            }

        self.call(f"{node}/change_state", kind, request, reply)

    def call(self, service: str, kind: Any, request: Any, reply: Reply) -> None:
        if service not in self.clients:
            self.clients[service] = self.node.create_client(kind, service)
        self.calls.append((time.monotonic() + MATCH_TIMEOUT_S, service, request, reply))

    def serve(self) -> None:
        """Call each service once it is there; print each response that came."""
        waiting: list[tuple[float, str, Any, Reply]] = []
        for deadline, service, request, reply in self.calls:
            if self.clients[service].service_is_ready():
                self.pending.append((self.clients[service].call_async(request), reply))
            elif time.monotonic() > deadline:
                say({"event": "error", "service": service, "error": "no such service"})
            else:
                waiting.append((deadline, service, request, reply))
        self.calls = waiting
        for future, reply in self.pending:
            if future.done():
                say(reply(future.result()))
        self.pending = [(future, reply) for future, reply in self.pending if not future.done()]

    def act_as_robot(self, namespace: str) -> None:
        from std_msgs.msg import String

        feedback = self.publisher(f"{namespace}/robot/feedback", String, "events")

        def on_command(message: Any) -> None:
            command = json.loads(message.data)
            say({"event": "msg", "topic": f"{namespace}/robot/command", "msg": command})
            if command.get("action") == "interrupt":
                answers = [(command.get("args", {}).get("target"), "interrupted")]
            else:
                answers = [(command["id"], "started"), (command["id"], "done")]
            for id_, status in answers:
                if id_:
                    feedback.publish(String(data=json.dumps({"id": id_, "status": status})))

        self.keep.append(
            self.node.create_subscription(
                String, f"{namespace}/robot/command", on_command, qos_of("events")
            )
        )
        say({"event": "robot", "namespace": namespace})


def main() -> int:
    rclpy.init()
    probe = Probe()
    orders: queue.Queue[dict[str, Any] | None] = queue.Queue()

    def read() -> None:
        for line in sys.stdin:
            if line.strip():
                orders.put(json.loads(line))
        orders.put(None)  # stdin closed: the test is gone

    threading.Thread(target=read, daemon=True).start()
    say({"event": "ready"})
    try:
        running = True
        while running:
            rclpy.spin_once(probe.node, timeout_sec=0.01)
            probe.flush()
            probe.serve()
            while running and not orders.empty():
                order = orders.get()
                running = order is not None and probe.order(order)
    finally:
        probe.node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
