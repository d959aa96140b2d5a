"""User profiles that learn: the profile store, preference prediction, feedback and
general questions (seed 001 "Memory" and "User-adaptive system"; seed 000 §3.2).

The controller loads or creates a profile at step 5 (:meth:`ProfileStore.get_or_create`),
chooses an entertainment activity with :class:`ActivityChooser` at step 6, records
feedback at step 7 and answers to :class:`QuestionBank` questions at step 8.
"""

from memory.errors import ProfileError, ProfileNotFound, SchemaOutOfDate, StoreUnavailable
from memory.preferences import ActivityChooser, PreferenceModel
from memory.profile import ActivityScore, Profile
from memory.questions import Question, QuestionBank
from memory.store import ProfileStore

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
