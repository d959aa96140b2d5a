"""The controller: the paper's decision loop, one tick at a time.

Files, in the order a newcomer reads them:

- ``choice.py``: what the robot does next: the reasons to cancel a running activity,
  the behavior of the dominant motivation when no user is there, and with a user an
  agenda item, a question, or an activity chosen by the user's proactivity. Start here.
- ``tick.py``: :class:`Controller` and its ``tick``: the steps of the loop in order,
  each under the fault barrier.
- ``dialogs.py`` (questions, feedback, "continue or stop?"), ``events.py`` (requests,
  touches, speech, screen choices), ``requests.py`` (the queue from the events to the
  choice), ``sessions.py`` (users, their sessions and
  profiles), ``running.py`` (the activity on its manager, the robot link), ``drives.py``
  (the motivation stepped every tick), ``decisions.py`` (a tick's decisions and why).
- ``state.py``: :class:`TickRecord`, what a tick leaves: its decisions and the state
  published on ``dms/state``.

``docs/paper.md`` maps each step of the paper to this code; ``docs/architecture.md``
shows where the controller stands among the packages.
"""

from dms.controller.deps import ControllerDeps, Counters
from dms.controller.running import Running
from dms.controller.state import TickRecord
from dms.controller.tick import Controller

__all__ = ["Controller", "ControllerDeps", "Counters", "Running", "TickRecord"]
