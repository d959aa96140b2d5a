"""The Reachy Mini bridge of dms: a Reachy Mini (real or simulated) as the daemon's robot.

It reaches the daemon over Zenoh only and imports nothing of dms (docs/reachy.md).
"""
