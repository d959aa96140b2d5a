"""``dms secure init`` and ``renew``: the files, their modes, the chain, the refusals.

The Zenoh side (who may do what over a real link) is tests/integration/test_secure.py.
"""

from __future__ import annotations

import ipaddress
import json
import os
import stat
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from dms import secure
from dms.cli import main
from dms.kernel.errors import ConfigError


def _load(path: Path) -> dict[str, object]:
    """A written ``.json5``: JSON after its ``//`` header lines."""
    lines = [line for line in path.read_text().splitlines() if not line.startswith("//")]
    loaded = json.loads("\n".join(lines))
    assert isinstance(loaded, dict)
    return loaded


def _cert(path: Path) -> x509.Certificate:
    return x509.load_pem_x509_certificate(path.read_bytes())


def test_init_writes_a_ca_and_per_role_key_cert_and_config(tmp_path: Path) -> None:
    out = tmp_path / "sec"
    written = secure.init(out, "mini", "tls/127.0.0.1:7500")
    names = {path.name for path in written}
    assert names == {"ca.pem", "ca.key"} | {
        f"{role}.{ext}" for role in secure.ROLES for ext in ("pem", "key", "json5")
    }
    assert {p.name for p in out.iterdir()} == names
    for path in written:
        mode = stat.S_IMODE(path.stat().st_mode)
        assert mode == (0o600 if path.suffix == ".key" else 0o644), path.name


def test_every_role_certificate_chains_to_the_ca_and_names_loopback(tmp_path: Path) -> None:
    secure.init(tmp_path, "mini", "tls/10.0.0.5:7500")
    ca = _cert(tmp_path / "ca.pem")
    ca.verify_directly_issued_by(ca)  # self-signed
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    for role in secure.ROLES:
        cert = _cert(tmp_path / f"{role}.pem")
        cert.verify_directly_issued_by(ca)
        cn = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value
        assert cn == secure.common_name(role, "mini") == f"{role}.mini.dms"
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        assert set(san.get_values_for_type(x509.IPAddress)) == {
            ipaddress.ip_address("10.0.0.5"),
            ipaddress.ip_address("127.0.0.1"),
        }
        assert san.get_values_for_type(x509.DNSName) == ["localhost"]
        assert not cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
        # the key on disk is the certificate's
        key = serialization.load_pem_private_key((tmp_path / f"{role}.key").read_bytes(), None)
        public = cert.public_key()
        assert isinstance(key, ec.EllipticCurvePrivateKey)
        assert isinstance(public, ec.EllipticCurvePublicKey)
        assert key.public_key().public_numbers() == public.public_numbers()


def test_the_daemon_listens_and_the_others_connect_on_tls_with_mtls(tmp_path: Path) -> None:
    secure.init(tmp_path, "r2", "tls/127.0.0.1:7600")
    for role in secure.ROLES:
        conf = _load(tmp_path / f"{role}.json5")
        listen, connect = conf["listen"], conf["connect"]
        if role == "dms":
            assert listen == {"endpoints": ["tls/127.0.0.1:7600"]}
            assert connect == {"endpoints": []}
        else:
            assert listen == {"endpoints": []}
            assert connect == {"endpoints": ["tls/127.0.0.1:7600"]}
        link = conf["transport"]["link"]  # type: ignore[index]
        assert link["protocols"] == ["tls"]
        tls = link["tls"]
        assert tls["enable_mtls"] is True and tls["verify_name_on_connect"] is True
        assert tls["root_ca_certificate"] == str((tmp_path / "ca.pem").resolve())
        assert tls["connect_certificate"] == str((tmp_path / f"{role}.pem").resolve())
        assert tls["connect_private_key"] == str((tmp_path / f"{role}.key").resolve())
        acl = conf["access_control"]
        assert acl["enabled"] is True and acl["default_permission"] == "deny"  # type: ignore[index]


def _allowed(role_conf: dict[str, object], subject: str, flow: str, message: str) -> set[str]:
    """Key expressions ``subject`` may exchange with ``message`` in ``flow``."""
    acl = role_conf["access_control"]
    assert isinstance(acl, dict)
    rule_ids = {
        rule_id
        for policy in acl["policies"]
        if subject in policy["subjects"]
        for rule_id in policy["rules"]
    }
    return {
        key
        for rule in acl["rules"]
        if rule["id"] in rule_ids and flow in rule["flows"] and message in rule["messages"]
        for key in rule["key_exprs"]
    }


def test_the_daemons_rules_give_each_role_only_its_keys(tmp_path: Path) -> None:
    secure.init(tmp_path, "mini")
    conf = _load(tmp_path / "dms.json5")
    acl = conf["access_control"]
    assert isinstance(acl, dict)
    assert {s["id"]: s["cert_common_names"] for s in acl["subjects"]} == {
        role: [f"{role}.mini.dms"] for role in secure.ROLES if role != "dms"
    }
    puts = {role: _allowed(conf, role, "ingress", "put") for role in secure.ROLES[1:]}
    assert puts == {
        "perception": {"robots/mini/perception/**", "robots/mini/params/**"},
        "robot": {"robots/mini/robot/feedback", "robots/mini/robot/joints"},
        "app": {"robots/mini/request"},
        "admin": {"robots/mini/request"},
        "face": {"robots/mini/perception/**"},
    }
    queries = {role: _allowed(conf, role, "ingress", "query") for role in secure.ROLES[1:]}
    assert queries == {
        "perception": set(),
        "robot": set(),
        "app": {"robots/mini/dms/**"},
        "admin": {
            "robots/mini/dms/**",
            "robots/mini/users/**",
            "robots/mini/agenda/**",
            "robots/mini/studio/try",
        },
        "face": set(),
    }
    assert _allowed(conf, "robot", "egress", "put") == {"robots/mini/robot/command"}
    assert _allowed(conf, "app", "egress", "put") == {
        "robots/mini/dms/**",
        "robots/mini/robot/joints",
    }
    assert _allowed(conf, "face", "egress", "put") == {
        "robots/mini/robot/command",
        "robots/mini/dms/state",
        "robots/mini/dms/decision",
    }
    assert _allowed(conf, "perception", "ingress", "liveliness_token") == {
        "robots/mini/alive/perception/**",
        "robots/mini/alive/params/**",
    }
    # A role's own file trusts only the daemon, with the same grants seen from its side.
    app = _load(tmp_path / "app.json5")
    assert _allowed(app, "dms", "egress", "put") == {"robots/mini/request"}
    assert _allowed(app, "dms", "egress", "query") == {"robots/mini/dms/**"}


def test_the_keys_granted_are_the_daemons_keys() -> None:
    """A renamed key in dms.kernel.keys must not leave the ACL granting a key nobody uses."""
    from dms.kernel import keys

    granted = {
        k.rstrip("*").rstrip("/")
        for grants in secure.GRANTS.values()
        for g in grants
        for k in g.keys
    }
    for key in (*keys.INPUT_KEYS, keys.DMS_STATE, keys.DMS_DECISION, keys.ROBOT_COMMAND):
        assert any(key == g or key.startswith(g + "/") for g in granted), key
    assert {keys.USERS_PREFIX[:-1], keys.AGENDA_PREFIX[:-1], keys.ALIVE_DMS} <= granted


def test_init_refuses_to_overwrite_without_force(tmp_path: Path) -> None:
    secure.init(tmp_path, "mini")
    before = (tmp_path / "ca.pem").read_bytes()
    with pytest.raises(ConfigError, match="--force"):
        secure.init(tmp_path, "mini")
    assert (tmp_path / "ca.pem").read_bytes() == before
    secure.init(tmp_path, "mini", force=True)
    assert (tmp_path / "ca.pem").read_bytes() != before


@pytest.mark.parametrize(
    ("robot_id", "listen", "message"),
    [
        ("Mini", secure.DEFAULT_LISTEN, "bad robot id 'Mini'"),
        ("mi/ni", secure.DEFAULT_LISTEN, "bad robot id"),
        ("mini", "tcp/127.0.0.1:7447", "bad endpoint 'tcp/127.0.0.1:7447'"),
        ("mini", "tls/127.0.0.1:0", "bad endpoint"),
        ("mini", "tls/127.0.0.1:70000", "bad endpoint"),
        ("mini", "tls/127.0.0.1", "bad endpoint"),
        ("mini\n", secure.DEFAULT_LISTEN, "bad robot id"),
        ("mini", "tls/127.0.0.1:7447\n", "bad endpoint"),
    ],
)
def test_bad_input_is_refused_before_anything_is_written(
    tmp_path: Path, robot_id: str, listen: str, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        secure.init(tmp_path / "sec", robot_id, listen)
    assert not (tmp_path / "sec").exists()


def test_cli_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    for args, expected in [
        (["--robot-id", "mini"], f"dms: cannot write into {blocker / 'sec'}"),
        (["--robot-id", "BAD"], "dms: bad robot id 'BAD'"),
        (["--robot-id", "mini", "--listen", "udp/1.2.3.4:5"], "dms: bad endpoint"),
    ]:
        assert main(["secure", "init", str(blocker / "sec"), *args]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(expected), err


def test_cli_init_lists_the_files_and_refuses_a_second_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["secure", "init", str(tmp_path), "--robot-id", "mini"]) == 0
    out = capsys.readouterr().out.split()
    assert str(tmp_path / "dms.json5") in out and len(out) == 2 + 3 * len(secure.ROLES)
    assert main(["secure", "init", str(tmp_path), "--robot-id", "mini"]) == 1
    assert "use --force" in capsys.readouterr().err


def test_renew_replaces_one_roles_key_from_the_same_ca(tmp_path: Path) -> None:
    secure.init(tmp_path, "mini", "tls/127.0.0.1:7500")
    old = _cert(tmp_path / "app.pem")
    old_key = (tmp_path / "app.key").read_bytes()
    other = (tmp_path / "admin.pem").read_bytes()
    secure.renew(tmp_path, "app")
    new = _cert(tmp_path / "app.pem")
    new.verify_directly_issued_by(_cert(tmp_path / "ca.pem"))
    assert new.serial_number != old.serial_number
    assert (tmp_path / "app.key").read_bytes() != old_key
    assert stat.S_IMODE((tmp_path / "app.key").stat().st_mode) == 0o600
    assert new.subject == old.subject
    san = x509.SubjectAlternativeName
    assert new.extensions.get_extension_for_class(san) == old.extensions.get_extension_for_class(
        san
    )
    assert (tmp_path / "admin.pem").read_bytes() == other
    with pytest.raises(ConfigError, match="unknown role"):
        secure.renew(tmp_path, "guest")
    with pytest.raises(ConfigError, match="cannot read the CA"):
        secure.renew(tmp_path / "elsewhere", "app")


def test_a_planted_symlink_is_refused_and_nothing_is_written_through_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder, victim = tmp_path / "sec", tmp_path / "victim"
    secure.init(folder, "mini")
    before = {path.name: path.read_bytes() for path in folder.iterdir()}
    (folder / "ca.key").unlink()
    (folder / "ca.key").symlink_to(victim)
    assert main(["secure", "init", str(folder), "--robot-id", "mini", "--force"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dms: {folder / 'ca.key'} is a symbolic link; refusing to write through it"]
    assert not victim.exists()
    assert (folder / "ca.pem").read_bytes() == before["ca.pem"]  # nothing written at all

    (folder / "app.key").unlink()
    (folder / "app.key").symlink_to(victim)
    assert main(["secure", "renew", str(folder), "app"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dms: {folder / 'app.key'} is a symbolic link; refusing to write through it"]
    assert not victim.exists()
    assert (folder / "app.pem").read_bytes() == before["app.pem"]


def test_a_dangling_symlink_is_refused_without_force_too(tmp_path: Path) -> None:
    (tmp_path / "dms.key").symlink_to(tmp_path / "elsewhere.key")
    with pytest.raises(ConfigError, match=r"dms\.key is a symbolic link"):
        secure.init(tmp_path, "mini")
    assert not (tmp_path / "elsewhere.key").exists() and not (tmp_path / "ca.key").exists()


def test_force_writes_new_files_and_keys_are_0600_whatever_the_old_mode(tmp_path: Path) -> None:
    secure.init(tmp_path, "mini")
    old = tmp_path / "ca.key"
    old.chmod(0o644)
    old_inode = old.stat().st_ino
    hard_link = tmp_path / "kept-elsewhere"
    os.link(old, hard_link)  # another name of the old file keeps its bytes untouched
    kept = hard_link.read_bytes()
    secure.init(tmp_path, "mini", force=True)
    assert stat.S_IMODE(old.stat().st_mode) == 0o600
    assert old.stat().st_ino != old_inode
    assert hard_link.read_bytes() == kept
    assert stat.S_IMODE((tmp_path / "ca.pem").stat().st_mode) == 0o644
