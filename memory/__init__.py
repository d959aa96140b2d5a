"""User profiles that learn: the profile store, preference prediction, feedback and
general questions (the paper's "Memory" and "User-adaptive system"; "Combining Finite
State Machine and Decision-Making Tools for Adaptable Robot Behavior", §3.2).

The controller loads or creates a profile at step 5 (:meth:`ProfileStore.get_or_create`),
chooses an entertainment activity with :class:`ActivityChooser` at step 6, records
feedback at step 7 and answers to :class:`QuestionBank` questions at step 8.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from memory.errors import ProfileError, ProfileNotFound, SchemaOutOfDate, StoreUnavailable

if TYPE_CHECKING:
    from memory.preferences import ActivityChooser, PreferenceModel
    from memory.profile import ActivityScore, Profile
    from memory.questions import Question, QuestionBank
    from memory.store import ProfileStore

# Imported on first use: a module that needs one small part of the package
# (memory.errors, memory.parameters for `dms rules`, memory.seed_data for the simulator)
# then loads in about 0.1 s instead of about 1 s with SQLAlchemy, numpy and the store.
_LAZY = {
    "ActivityChooser": "memory.preferences",
    "PreferenceModel": "memory.preferences",
    "ActivityScore": "memory.profile",
    "Profile": "memory.profile",
    "Question": "memory.questions",
    "QuestionBank": "memory.questions",
    "ProfileStore": "memory.store",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'memory' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


__all__ = [
    "ActivityChooser",
    "ActivityScore",
    "PreferenceModel",
    "Profile",
    "ProfileError",
    "ProfileNotFound",
    "ProfileStore",
    "Question",
    "QuestionBank",
    "SchemaOutOfDate",
    "StoreUnavailable",
]
