"""What the Mini can do with its body, its cheeks and its screen, by name.

A behavior names a gesture, an LED pattern or a screen face as a string; the robot does
nothing visible with a name it does not know, so ``dms behavior check`` and the loader
refuse one that is not listed here. The simulated Mini times these gestures
(``sim.robot.MOTION_SECONDS``); a robot with another repertoire changes these lists.

Part of the kernel: it imports nothing of the project.
"""

from __future__ import annotations

GESTURES: tuple[str, ...] = (
    "nod",
    "shake_head",
    "wave",
    "bow",
    "look_around",
    "think",
    "celebrate",
    "shrug",
    "sleep_pose",
    "wake_up",
    "dance_step",
    "clap",
)
"""The gestures of the ``motion`` channel's ``gesture`` command."""

LED_PATTERNS: tuple[str, ...] = ("solid", "blink", "pulse", "breathing")
"""How the cheek and heart LEDs light (the ``led`` channel's ``set``)."""

FACES: tuple[str, ...] = ("neutral", "happy", "sad", "surprised", "closed_eyes")
"""The screen eyes (the ``screen`` channel's ``show`` with a ``face``)."""
