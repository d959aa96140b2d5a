"""A fleet's router with mutual TLS and access control.

``dms secure init`` writes the CA and each role's certificate. Here the
router (``dms router --zenoh-config``) listens on mutual TLS and is the point where
access control is enforced: its JSON5 denies the ``app`` role the residents' data
(``users/*`` queries) and allows the rest. A daemon connects to it over TLS; the
``admin`` role reads a profile through the router, the ``app`` role reads the state but
gets nothing of the profile. Every process is real, on 127.0.0.1.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from tests.integration.harness import READY_TIMEOUT_S, free_port, wait_token

pytestmark = pytest.mark.integration


def _dms(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "dms.cli", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        text=True,
    )


def _json5(path: Path) -> dict[str, Any]:
    """A file ``dms secure init`` wrote: JSON after its comment lines."""
    lines = path.read_text().splitlines()
    return dict(json.loads("\n".join(ln for ln in lines if not ln.lstrip().startswith("//"))))


def _write(path: Path, config: dict[str, Any]) -> Path:
    path.write_text(json.dumps(config, indent=2))
    return path


def _router_config(dms: dict[str, Any], robot: str) -> dict[str, Any]:
    """The daemon role's TLS, in router mode, with the fleet's access control."""
    config = dict(dms, mode="router")
    config["access_control"] = {
        "enabled": True,
        "default_permission": "allow",
        "rules": [
            {
                "id": "no-personal-data-for-apps",
                "permission": "deny",
                "flows": ["ingress", "egress"],
                "messages": ["query", "reply"],
                "key_exprs": [f"robots/{robot}/users/**", f"robots/{robot}/agenda/**"],
            }
        ],
        "subjects": [{"id": "app", "cert_common_names": [f"app.{robot}.dms"]}],
        "policies": [{"subjects": ["app"], "rules": ["no-personal-data-for-apps"]}],
    }
    return config


def _client(role: dict[str, Any]) -> zenoh.Session:
    """A client of the router with ``role``'s certificate; it waits for the router to
    listen (the connection is tried again until it is up or the wait is over)."""
    mine = dict(role, mode="client")
    mine["access_control"] = {"enabled": False}  # the router enforces the fleet's rules
    config = zenoh.Config.from_json5(json.dumps(mine))
    config.insert_json5("connect/timeout_ms", str(int(READY_TIMEOUT_S * 1000)))
    config.insert_json5(
        "connect/retry", "{period_init_ms: 50, period_max_ms: 50, period_increase_factor: 1}"
    )
    return zenoh.open(config)


def _query(session: zenoh.Session, key: str) -> list[Any]:
    return [json.loads(r.ok.payload.to_bytes()) for r in session.get(key, timeout=5.0) if r.ok]


@contextmanager
def _secured_fleet(tmp: Path) -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    router_port, daemon_port = free_port(), free_port()
    keys_dir = tmp / "secure"
    made = subprocess.run(
        [sys.executable, "-m", "dms.cli", "secure", "init", str(keys_dir), "--robot-id",
         "hall", "--listen", f"tls/127.0.0.1:{router_port}"],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert made.returncode == 0, made.stderr
    dms = _json5(keys_dir / "dms.json5")
    router = _write(tmp / "router.json5", _router_config(dms, "hall"))
    daemon = dict(dms)
    daemon["listen"] = {"endpoints": [f"tls/127.0.0.1:{daemon_port}"]}
    daemon["connect"] = {"endpoints": [f"tls/127.0.0.1:{router_port}"]}
    daemon["access_control"] = {"enabled": False}  # behind the router, which enforces it
    daemon_file = _write(tmp / "daemon.json5", daemon)
    toml = tmp / "dms.toml"
    # new_user_after_s = 0: Ann's profile is stored at once, not after she has stayed
    toml.write_text("[privacy]\nserve_profiles = true\n[controller]\nnew_user_after_s = 0\n")
    with ExitStack() as stack:
        router_proc = _dms("router", "--zenoh-config", str(router))
        stack.callback(router_proc.kill)
        admin = _client(_json5(keys_dir / "admin.json5"))
        stack.callback(admin.close)
        assert list(admin.info.routers_zid()), "no TLS link to the router"
        daemon_proc = _dms(
            "run", "--config", str(toml), "--zenoh-config", str(daemon_file), "--robot-id",
            "hall", "--db", f"sqlite:///{tmp / 'dms.db'}", "--quiet",
        )  # fmt: skip
        stack.callback(daemon_proc.kill)
        wait_token(admin, "robots/hall/alive/dms")
        app = _client(_json5(keys_dir / "app.json5"))
        stack.callback(app.close)
        yield admin, app


def test_the_router_speaks_tls_and_keeps_personal_data_from_apps(tmp_path: Path) -> None:
    with _secured_fleet(tmp_path) as (admin, app):
        states: list[dict[str, Any]] = []
        seen = threading.Condition()

        def on_state(sample: zenoh.Sample) -> None:
            with seen:
                states.append(json.loads(sample.payload.to_bytes()))
                seen.notify_all()

        watch = admin.declare_subscriber("robots/hall/dms/state", on_state)
        admin.put("robots/hall/perception/user", json.dumps(
            {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}
        ))  # fmt: skip
        with seen:  # her session began and her profile is stored
            assert seen.wait_for(
                lambda: any(
                    (s["user"] or {}).get("id") == "ann" and s["pending_writes"] == 0
                    for s in states
                ),
                READY_TIMEOUT_S,
            ), states[-3:]
        watch.undeclare()
        assert _query(admin, "robots/hall/users/ann"), "the admin reads Ann's profile"
        assert _query(app, "robots/hall/dms/state"), "the app reads the state over TLS"
        assert _query(app, "robots/hall/users/ann") == [], "the router denies it the profile"
        assert _query(app, "robots/hall/users/*") == []
