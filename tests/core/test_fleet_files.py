"""The fleet's shipped configuration files load as they are (deploy/fleet/)."""

from __future__ import annotations

from pathlib import Path

from dms.bus import ZenohRouter, make_router_config
from dms.config import load_config

FLEET = Path(__file__).resolve().parents[2] / "deploy" / "fleet"


def test_the_robot_configuration_loads() -> None:
    settings = load_config(FLEET / "robot.toml", robot_id="hall")
    assert settings.robot_id == "hall"
    assert settings.db is not None and settings.db.startswith("postgresql+psycopg://")
    assert settings.zenoh.connect == ["tcp/127.0.0.1:7447"]


def test_the_router_configuration_opens_a_router(tmp_path: Path) -> None:
    text = (FLEET / "router.json5").read_text().replace("127.0.0.1:7447", "127.0.0.1:0")
    config_file = tmp_path / "router.json5"
    config_file.write_text(text)
    router = ZenohRouter(make_router_config((), config_file))
    try:
        assert router.zid
    finally:
        router.close()
