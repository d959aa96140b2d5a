"""The daemon's configuration: defaults, a TOML file, ``DMS_*`` environment variables,
then command-line flags, each over the one before (docs/configuration.md).

pydantic-settings layers them: :func:`load_config` builds the settings from three of its
sources, the flags (its init source), the environment (its env source) and the file (an
init source over the file's tables, as its TOML source is), merged table by table.

Every setting has an environment variable: ``DMS_`` and its name in capitals, with
``__`` between a section and its field (``DMS_DB``, ``DMS_ROBOT_ID``,
``DMS_CONTROLLER__TICK_PERIOD_S``); lists and tables are JSON
(``DMS_ZENOH__CONNECT='["tcp/10.0.0.2:7447"]'``). pydantic-settings reads them.

Every section is validated by pydantic; a wrong value is reported as one line naming
the file or the variable, the field and what was wrong
(:class:`dms.kernel.errors.ConfigError`).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_settings import (
    BaseSettings,
    EnvSettingsSource,
    InitSettingsSource,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    SettingsError,
)

from dms.kernel.errors import ConfigError
from dms.kernel.keys import INPUT_KEYS, ROBOT_ID_RE
from dms.kernel.tomlfile import read_toml

Fraction = float


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ZenohSettings(_Section):
    listen: list[str] = Field(default_factory=lambda: ["tcp/127.0.0.1:7447"])
    connect: list[str] = Field(default_factory=list)
    config_file: Path | None = None

    @model_validator(mode="before")
    @classmethod
    def _file_endpoints(cls, data: Any) -> Any:
        """With a Zenoh configuration file and no ``listen`` given, the file's own
        endpoints (tls/..., quic/...) stand instead of the default one."""
        if isinstance(data, dict) and data.get("config_file") and "listen" not in data:
            return {**data, "listen": []}
        return data


_STALE_AFTER_S: dict[str, float | None] = {
    "perception/user": 5.0,
    "perception/objects": 5.0,
    "robot/joints": 5.0,
}
_USER_INITIATIVE: dict[Literal["high", "moderate", "low", "unknown"], float] = {
    "high": 0.8,
    "moderate": 0.5,
    "unknown": 0.5,
    "low": 0.2,
}


QUERY_CAP_KEYS = (
    "dms/state",
    "dms/behavior",
    "dms/decisions",
    "dms/config",
    "users/*",
    "agenda/*",
)
"""The queryables, as ``[inputs] rate_cap_per_s`` names them (``users/*``: every
``users/<id>``)."""

_RATE_CAP_PER_S: dict[str, float | None] = {
    "perception/user": 100.0,
    "perception/objects": 100.0,
    "robot/joints": 200.0,
    "perception/touch": 50.0,
    "perception/speech": 50.0,
    "perception/screen": 50.0,
    "params/robot": 50.0,
    "params/env": 50.0,
    "request": 50.0,
    "robot/feedback": 500.0,
    "dms/state": 100.0,
    "dms/behavior": 50.0,
    "dms/decisions": 50.0,
    "dms/config": 10.0,
    "users/*": 50.0,
    "agenda/*": 50.0,
}
"""Far above what a camera, a joint encoder, a microphone, an app or a viewer sends; a
flood beyond is dropped (a query over its cap gets an error reply at once)."""


def _positive_per_key(
    value: dict[str, float | None], known: tuple[str, ...], kind: str
) -> dict[str, float | None]:
    for key, amount in value.items():
        if key not in known:
            raise ValueError(f"{key!r} is not {kind}")
        if amount is not None and amount <= 0:
            raise ValueError(f"{key}: must be > 0")
    return value


class InputSettings(_Section):
    stale_after_s: dict[str, float | None] = Field(default_factory=lambda: _STALE_AFTER_S.copy())
    rate_cap_per_s: dict[str, float | None] = Field(default_factory=lambda: _RATE_CAP_PER_S.copy())
    """Messages (or queries) a second admitted per input key or queryable (None: no cap);
    the rest are dropped and counted, and the counts reported on ``dms/errors`` once a
    second."""
    error_reports_per_s: float = Field(20.0, gt=0.0)
    """Rejected messages reported on ``dms/errors`` (and logged) a second per key; the
    rest are counted, and the count reported once a second."""
    max_param_names: int = Field(256, ge=1)
    """Distinct names kept per params key (``params/robot``, ``params/env``); past it the
    name set longest ago is dropped, and the count reported once a second."""

    @field_validator("stale_after_s")
    @classmethod
    def _input_keys(cls, value: dict[str, float | None]) -> dict[str, float | None]:
        return _positive_per_key(value, INPUT_KEYS, "an input key")

    @field_validator("rate_cap_per_s")
    @classmethod
    def _capped_keys(cls, value: dict[str, float | None]) -> dict[str, float | None]:
        return _positive_per_key(value, INPUT_KEYS + QUERY_CAP_KEYS, "an input key or a queryable")

    def rate_caps(self) -> dict[str, float]:
        """The caps in force: the defaults, overridden by the file, without the None ones."""
        merged = {**_RATE_CAP_PER_S, **self.rate_cap_per_s}
        return {key: rate for key, rate in merged.items() if rate is not None}

    def report_caps(self) -> dict[str, float]:
        """The cap on rejection reports, the same for every input key and queryable."""
        return dict.fromkeys(INPUT_KEYS + QUERY_CAP_KEYS, self.error_reports_per_s)


class PrivacySettings(_Section):
    serve_profiles: bool = False
    """Answer ``users/*`` and ``agenda/*`` queries from other processes. Off by default:
    a resident's data leaves the daemon only when a deployment says so (and, secured,
    only to the admin role)."""


class FrameSettings(_Section):
    """How long a perceived frame is live: after it, a behavior sees its last
    known pose with its age, and ``attend`` holds the gaze, then returns to neutral."""

    face_live_s: float = Field(2.0, gt=0.0)
    """A face not seen again for this long is last known (the person turned away)."""
    object_live_s: float = Field(2.0, gt=0.0)
    """An object or tag not seen again for this long is last known."""


class ControllerSettings(_Section):
    tick_period_s: float = Field(0.5, gt=0.0, le=10.0)
    confirm_timeout_s: float = Field(10.0, gt=0.0)
    """How long the shoulder dialog waits for "continue" or "stop" before resuming."""
    question_timeout_s: float = Field(15.0, gt=0.0)
    chooser: Literal["ranking", "explore"] = "ranking"
    """How the robot picks an entertainment activity by itself: ``ranking``, the paper's
    (the best of the user's predicted preferences not just done), or ``explore`` (now and
    then an activity she never did, otherwise Thompson sampling: a better ranking learnt,
    worse choices meanwhile; docs/simulation.md measures both)."""
    menu_timeout_s: float = Field(120.0, gt=0.0)
    """A menu of activities with no answer for this long ends: the user is not answering
    (a failure of the paper's Table 4) and the robot chooses. The value is assumed, not
    measured (the paper gives none): long enough for a first-time user to look through
    the menu, short enough that no one is left waiting. It counts from the menu's first
    offer, a reminder that cuts the menu and offers it again does not start it over; a
    try at an answer the menu did not understand (it asks again) does."""
    feedback_probability: float = Field(0.5, ge=0.0, le=1.0)
    session_questions: int = Field(4, ge=0, le=50)
    """General questions asked when a session starts (the paper: 4-5)."""
    question_every: int = Field(3, ge=0)
    """Then one more general question every N activities (0: never)."""
    user_initiative: dict[Literal["high", "moderate", "low", "unknown"], float] = Field(
        default_factory=lambda: _USER_INITIATIVE.copy()
    )
    """Probability that the user takes the initiative, by proactivity."""
    ack_timeout_s: float = Field(10.0, gt=0.0)
    """A robot command not acknowledged within this fails its activity."""
    done_timeout_s: float = Field(120.0, gt=0.0)
    """A robot command started but not done within this (plus a media's length) fails it."""
    min_speech_confidence: float = Field(0.5, ge=0.0, le=1.0)
    """An utterance recognized with less confidence is not understood (the question waits)."""
    perception_grace_s: float = Field(60.0, gt=0.0)
    """How long a session outlives stale or missing ``perception/user`` (the user is then
    unknown, not gone: the activity goes on, nothing new starts) before it ends."""
    resume_cut_within_s: float = Field(0.0, ge=0.0)
    """A user seen again, at this robot or another of the fleet, within this long after a
    session end (she left) cut her activity, gets that activity again, started afresh
    (reason ``resumed``); 0, the default: never (a robot does not carry on with what
    another one was doing)."""
    cleanup_limit_s: float = Field(10.0, ge=0.0)
    """A cancelled activity's cleanup states (the quiz saying it stops) may run this long;
    0 stops activities at once, without cleanup."""
    offline_after_unacked: int = Field(3, ge=1)
    """Commands in a row the robot never acknowledges before it is marked offline."""
    offline_retry_max_s: float = Field(300.0, gt=0.0)
    """While offline, an activity is tried again after a wait that doubles up to this."""
    new_user_after_s: float = Field(3.0, ge=0.0)
    """A user id the store does not know gets a profile once seen ready and engaged this
    long without a break; until then nothing is stored for it (0: at once)."""
    new_profiles_per_hour: int = Field(20, ge=0)
    """New profiles made at most an hour; the ids over it are served without a profile,
    and their count reported on ``dms/errors``."""

    @field_validator("user_initiative")
    @classmethod
    def _probabilities(cls, value: dict[str, float]) -> dict[str, float]:
        for level, p in value.items():
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{level}: {p} is not a probability in [0, 1]")
        return value


class RulesSettings(_Section):
    files: list[Path] = Field(default_factory=list)
    schema_file: Path | None = None


class BehaviorsSettings(_Section):
    folder: Path | None = None
    """A folder of behavior files; None means the shipped behaviors."""
    watch_s: float = Field(1.0, ge=0.0)
    """How often ``dms run`` looks for changed behavior files (the folder's ``*.yaml``)
    and rules files, to reload them by itself once a change holds still for one look
    (:mod:`dms.watch`); 0: only SIGHUP and ``reload_rules`` reload them."""


class StorageSettings(_Section):
    """``[storage]``: where acknowledged writes wait when the database cannot take them."""

    spool_dir: Path | None = None
    """A folder on another filesystem for the write spool, used when the one beside the
    database cannot be written (a full disk, a read-only or failing one); None: none."""
    memory_bound: int = Field(default=10_000, ge=1)
    """Writes kept in memory when no spool can be written; past it new writes are
    dropped, and that is reported."""


class Settings(_Section):
    """Everything ``dms run`` needs."""

    robot_id: str = "mini"
    db: str | None = None
    """SQLAlchemy URL; None means a SQLite file in the user's data folder."""
    robot: Literal["sim", "zenoh"] = "sim"
    seed: int | None = None
    timezone: str = "UTC"
    log_level: Literal["debug", "info", "warning", "error"] = "info"
    """The least severe log record written to stderr."""
    log_format: Literal["text", "json"] = "text"
    """Log lines as text, or one JSON object a line (with the structured fields)."""
    zenoh: ZenohSettings = Field(default_factory=ZenohSettings)
    inputs: InputSettings = Field(default_factory=InputSettings)
    controller: ControllerSettings = Field(default_factory=ControllerSettings)
    rules: RulesSettings = Field(default_factory=RulesSettings)
    behaviors: BehaviorsSettings = Field(default_factory=BehaviorsSettings)
    privacy: PrivacySettings = Field(default_factory=PrivacySettings)
    frames: FrameSettings = Field(default_factory=FrameSettings)
    storage: StorageSettings = Field(default_factory=StorageSettings)
    motivation: dict[str, Any] = Field(default_factory=dict)
    """Validated by the motivation package's own model."""
    source: Path | None = Field(default=None, exclude=True)

    @field_validator("robot_id")
    @classmethod
    def _robot_id(cls, value: str) -> str:
        if not ROBOT_ID_RE.fullmatch(value):
            raise ValueError(f"{value!r} does not match [a-z0-9_-]+")
        return value


ENV_PREFIX = "DMS_"
ENV_NESTED = "__"


def environment() -> dict[str, Any]:
    """The settings ``DMS_*`` environment variables give, as nested raw values."""
    try:
        found = EnvSettingsSource(_layers(None, True))()
    except Exception as error:  # pydantic-settings' SettingsError: a JSON value is not JSON
        raise ConfigError(_not_json(error)) from None
    found.pop("source", None)
    return found


def _not_json(error: Exception) -> str:
    """One line naming the variable whose list or table is not JSON."""
    field = re.search(r'field "(\w+)"', str(error))
    prefix = env_name([field.group(1)]) if field else ENV_PREFIX
    mine = [(name, value) for name, value in os.environ.items() if name.upper().startswith(prefix)]
    # A value that looks like JSON and is not first, then any value that is not JSON.
    mine.sort(key=lambda item: (item[1].strip()[:1] not in ("[", "{"), item[0]))
    for name, value in mine:
        try:
            json.loads(value)
        except ValueError as bad:
            return f'{name} (environment): not JSON ({bad}); write lists as ["a", "b"]'
    return f"environment: {str(error).splitlines()[0]}"


def env_name(loc: Sequence[int | str]) -> str:
    """The environment variable of a field's location (``("zenoh", "connect")``)."""
    return ENV_PREFIX + ENV_NESTED.join(str(part) for part in loc).upper()


MAX_LISTED = 10
"""Wrong settings listed in the one line of a configuration error; the rest are counted."""


def _describe(error: ValidationError, where: str, env: dict[str, Any] | None = None) -> str:
    """Every wrong setting on one line, each with its place (the file, or the variable
    that gave it) and, for a misspelt name, the name it probably meant."""
    parts: list[str] = []
    shown = ""
    for detail in error.errors(include_url=False)[:MAX_LISTED]:
        loc = detail["loc"]
        field = ".".join(str(part) for part in loc) or "(top level)"
        place = f"{env_name(loc[:2])} (environment)" if env and _given(env, loc) else where
        message = detail["msg"].removeprefix("Value error, ")
        if detail["type"] == "extra_forbidden":
            message += _did_you_mean(loc)
        parts.append(f"{field}: {message}" if place == shown else f"{place}: {field}: {message}")
        shown = place
    more = error.error_count() - MAX_LISTED
    tail = f"; and {more} more" if more > 0 else ""
    return "; ".join(parts) + tail


def _did_you_mean(loc: Sequence[int | str]) -> str:
    """`` (did you mean NAME?)`` for a misspelt setting at ``loc``, else ``""``."""
    from difflib import get_close_matches

    model: type[BaseModel] = Settings
    for part in loc[:-1]:
        info = model.model_fields.get(str(part))
        annotation = info.annotation if info is not None else None
        if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
            return ""
        model = annotation
    names = [name for name, info in model.model_fields.items() if not info.exclude]
    close = get_close_matches(str(loc[-1]), names, n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def _given(data: dict[str, Any], loc: Sequence[int | str]) -> bool:
    """Whether ``data`` holds a value at the start of ``loc`` (its section's field)."""
    node: Any = data
    for part in loc[:2]:
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


class _TomlFile(InitSettingsSource):
    """The settings of a TOML file, as pydantic-settings' own TOML source gives them (an
    init source over the file's tables), read by :func:`read_toml` instead: a missing
    file or a syntax error is one line naming the file, and the file's relative paths
    are taken from its folder."""

    def __init__(self, settings_cls: type[BaseSettings], path: Path) -> None:
        data = read_toml(path)
        _resolve_paths(data, path.parent)
        super().__init__(settings_cls, data)


@lru_cache(maxsize=16)
def _layers(path: Path | None, use_environment: bool) -> type[BaseSettings]:
    """The settings class whose keywords (the flags) are over the ``DMS_*`` environment
    (if ``use_environment``), over the TOML file at ``path`` (if any), over the defaults.

    One class for each file (the file is read each time the class is instantiated, so
    a reload sees its changes); at most a few files are ever loaded in one process."""

    class Layers(BaseSettings, Settings):
        model_config = SettingsConfigDict(
            env_prefix=ENV_PREFIX, env_nested_delimiter=ENV_NESTED, extra="forbid"
        )

        @classmethod
        def settings_customise_sources(
            cls,
            settings_cls: type[BaseSettings],
            init_settings: PydanticBaseSettingsSource,
            env_settings: PydanticBaseSettingsSource,
            dotenv_settings: PydanticBaseSettingsSource,
            file_secret_settings: PydanticBaseSettingsSource,
        ) -> tuple[PydanticBaseSettingsSource, ...]:
            # the first source that gives a value wins; tables merge field by field
            sources = [init_settings]
            if use_environment:
                sources.append(env_settings)
            if path is not None:
                sources.append(_TomlFile(settings_cls, path))
            return tuple(sources)

    return Layers


def load_config(
    path: Path | None = None,
    *,
    robot_id: str | None = None,
    db: str | None = None,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] | None = None,
    zenoh_config: Path | None = None,
    robot: str | None = None,
    seed: int | None = None,
    log_level: str | None = None,
    log_format: str | None = None,
    use_environment: bool = True,
) -> Settings:
    """The settings: defaults, then ``path`` (TOML) if given, then the ``DMS_*``
    environment variables (unless ``use_environment`` is False), then the flags that
    were set; each over the one before."""
    where = str(path) if path is not None else "configuration"
    flags: dict[str, Any] = {
        "robot_id": robot_id,
        "db": db,
        "robot": robot,
        "seed": seed,
        "log_level": log_level,
        "log_format": log_format,
    }
    given = {name: value for name, value in flags.items() if value is not None}
    zenoh: dict[str, Any] = {}
    if listen:
        zenoh["listen"] = list(listen)
    if connect:
        zenoh["connect"] = list(connect)
    if zenoh_config is not None:
        zenoh["config_file"] = zenoh_config
    if zenoh:
        given["zenoh"] = zenoh
    try:
        layered = _layers(path, use_environment)(**given)
    except SettingsError as error:  # a DMS_* list or table that is not JSON
        raise ConfigError(_not_json(error)) from None
    except ValidationError as error:
        env = environment() if use_environment else {}
        from_env = {name: value for name, value in env.items() if flags.get(name) is None}
        raise ConfigError(_describe(error, where, from_env)) from None
    fields = {name: getattr(layered, name) for name in Settings.model_fields}
    settings = Settings.model_construct(layered.model_fields_set, **fields)
    settings.source = path
    folder = settings.behaviors.folder
    if folder is not None and not folder.is_dir():
        raise ConfigError(f"{where}: behaviors.folder: {folder} is not a directory")
    return settings


def _resolve_paths(data: dict[str, Any], base: Path) -> None:
    """The file's relative paths (rules, behaviors, the spare spool folder) are relative
    to the file's folder."""
    rules = data.get("rules")
    if isinstance(rules, dict) and isinstance(rules.get("files"), list):
        rules["files"] = [
            str(base / f) if isinstance(f, str) and not Path(f).is_absolute() else f
            for f in rules["files"]
        ]
    behaviors = data.get("behaviors")
    if isinstance(behaviors, dict) and isinstance(behaviors.get("folder"), str):
        folder = Path(behaviors["folder"])
        if not folder.is_absolute():
            behaviors["folder"] = str(base / folder)
    storage = data.get("storage")
    if isinstance(storage, dict) and isinstance(storage.get("spool_dir"), str):
        spool_dir = Path(storage["spool_dir"])
        if not spool_dir.is_absolute():
            storage["spool_dir"] = str(base / spool_dir)
