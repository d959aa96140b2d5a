"""``dms secure init``: a certificate authority and a Zenoh config per role.

Out of the box the daemon answers anyone who reaches its port. A deployment beside
people needs two locks, and Zenoh has both: mutual TLS (only holders of a certificate
signed by the deployment's own CA connect at all) and access control (what each
certificate may put, subscribe to and query). This module writes both as plain files so
that they can be read, reviewed and versioned: ``ca.pem``, ``<role>.pem``,
``<role>.key`` (mode 0600) and ``<role>.json5`` for each of :data:`ROLES`.

The roles and what each may do are in :data:`GRANTS`; ``docs/security.md`` says the
same for people. Each grant is written twice: into ``dms.json5`` (the daemon's peer,
where it is enforced against the role's certificate common name) and into the role's
own file (against the daemon's common name), so that, for example, the robot takes
``robot/command`` only from the daemon even if another certificate holder listened
somewhere and the robot connected to it.

Pure: no Zenoh here (``dms.bus`` is the only module that imports it); the configs are
dicts that Zenoh's ``Config.from_file`` reads back.
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from dms.kernel.errors import ConfigError
from dms.kernel.keys import ROBOT_ID_RE

ROLES = ("dms", "perception", "robot", "app", "admin", "face")
"""``dms`` is the daemon; the others are the programs around it."""

DEFAULT_LISTEN = "tls/127.0.0.1:7447"
CA_DAYS = 3650
"""The CA outlives the role certificates: rotating a role does not touch the others."""
CERT_DAYS = 825
"""A role certificate's validity; ``docs/security.md`` says how to rotate one."""

_ENDPOINT_RE = re.compile(r"tls/(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):(?P<port>\d{1,5})")

Flow = Literal["ingress", "egress"]
Message = Literal[
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
]


@dataclass(frozen=True)
class Grant:
    """Messages a role may exchange with the daemon on some keys.

    ``flow`` is seen from the role: ``egress`` is what the role sends to the daemon,
    ``ingress`` what it takes from it. Keys are relative to ``robots/<id>/``.
    """

    name: str
    flow: Flow
    messages: tuple[Message, ...]
    keys: tuple[str, ...]


def _watch_daemon() -> tuple[Grant, ...]:
    """Every role may learn whether the daemon is up (``alive/dms``) and nothing else
    about liveliness: it is how a program waits for the daemon before it talks.

    Peers push their tokens to each other, so receiving the token is all it takes: a
    liveliness subscriber or ``liveliness().get`` on ``alive/dms`` is answered from the
    tokens the peer already holds (tested: granting ``declare_liveliness_subscriber`` and
    ``liveliness_query`` changes nothing, so they are not granted).
    """
    return (Grant("see-dms-alive", "ingress", ("liveliness_token",), ("alive/dms",)),)


def _input_module(keys: tuple[str, ...]) -> tuple[Grant, ...]:
    """A module feeding the daemon ``keys``: it puts them, declares their liveliness
    tokens (``alive/<key>``), and sees the daemon's subscriptions to them (without
    which Zenoh routes its puts nowhere: a denied ``declare_subscriber`` silently drops
    every put). The daemon's liveliness subscriber need not reach the module: peers push
    tokens without it."""
    return (
        Grant("put-inputs", "egress", ("put",), keys),
        Grant("input-tokens", "egress", ("liveliness_token",), tuple(f"alive/{k}" for k in keys)),
        Grant("dms-subscribes-inputs", "ingress", ("declare_subscriber",), keys),
    )


def _app() -> tuple[Grant, ...]:
    """A caregiver's app: requests in, everything the daemon publishes out."""
    return (
        Grant("put-request", "egress", ("put",), ("request",)),
        Grant("dms-subscribes-request", "ingress", ("declare_subscriber",), ("request",)),
        Grant("subscribe-dms", "egress", ("declare_subscriber",), ("dms/**",)),
        Grant("receive-dms", "ingress", ("put",), ("dms/**",)),
        Grant("query-dms", "egress", ("query",), ("dms/**",)),
        Grant("dms-answers", "ingress", ("reply", "declare_queryable"), ("dms/**",)),
        # Where the robot looks (the simulated Mini's joints, published by the daemon).
        Grant("subscribe-joints", "egress", ("declare_subscriber",), ("robot/joints",)),
        Grant("receive-joints", "ingress", ("put",), ("robot/joints",)),
    )


GRANTS: dict[str, tuple[Grant, ...]] = {
    "perception": (*_input_module(("perception/**", "params/**")), *_watch_daemon()),
    "robot": (
        *_input_module(("robot/feedback", "robot/joints")),
        Grant("subscribe-command", "egress", ("declare_subscriber",), ("robot/command",)),
        Grant("receive-command", "ingress", ("put",), ("robot/command",)),
        *_watch_daemon(),
    ),
    "app": (*_app(), *_watch_daemon()),
    # dms face: a person's perception in, what the robot says and shows and the daemon's
    # state and decisions out; no personal data (the picker then lists nobody).
    "face": (
        *_input_module(("perception/**",)),
        Grant("subscribe-command", "egress", ("declare_subscriber",), ("robot/command",)),
        Grant("receive-command", "ingress", ("put",), ("robot/command",)),
        Grant("subscribe-dms", "egress", ("declare_subscriber",), ("dms/state", "dms/decision")),
        Grant("receive-dms", "ingress", ("put",), ("dms/state", "dms/decision")),
        *_watch_daemon(),
    ),
    "admin": (
        *_app(),
        # Reading a profile or an agenda, and changing an agenda (a query with a payload).
        Grant("query-personal", "egress", ("query",), ("users/**", "agenda/**")),
        Grant(
            "personal-answers", "ingress", ("reply", "declare_queryable"), ("users/**", "agenda/**")
        ),
        # Trying a behavior from the studio on the robot (the daemon serves it only while
        # nobody is in a session).
        Grant("query-try", "egress", ("query",), ("studio/try",)),
        Grant("try-answers", "ingress", ("reply", "declare_queryable"), ("studio/try",)),
        *_watch_daemon(),
    ),
}
"""What each role may exchange with the daemon; anything else is denied."""


def common_name(role: str, robot_id: str) -> str:
    """The certificate common name of ``role`` for one robot: what the ACL matches."""
    return f"{role}.{robot_id}.dms"


def check_robot_id(robot_id: str) -> str:
    if not ROBOT_ID_RE.fullmatch(robot_id):
        raise ConfigError(f"bad robot id {robot_id!r}: use lower-case letters, digits, _ and -")
    return robot_id


def parse_listen(endpoint: str) -> tuple[str, int]:
    """(host, port) of a ``tls/HOST:PORT`` endpoint; ConfigError otherwise."""
    match = _ENDPOINT_RE.fullmatch(endpoint)
    port = int(match.group("port")) if match else 0
    if match is None or not 0 < port < 65536:
        raise ConfigError(
            f"bad endpoint {endpoint!r}: expected tls/HOST:PORT (mutual TLS needs tls/)"
        )
    return match.group("host").strip("[]"), port


# ------------------------------------------------------------------ certificates


@dataclass(frozen=True)
class Issued:
    """A key and its certificate."""

    key: ec.EllipticCurvePrivateKey
    cert: x509.Certificate


def _name(cn: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "dms"),
            x509.NameAttribute(NameOID.COMMON_NAME, cn),
        ]
    )


def make_ca(robot_id: str, now: datetime.datetime | None = None) -> Issued:
    """A self-signed CA for one robot's deployment (P-256 ECDSA)."""
    now = now or datetime.datetime.now(datetime.UTC)
    key = ec.generate_private_key(ec.SECP256R1())
    name = _name(f"dms CA {robot_id}")
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=CA_DAYS))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return Issued(key, cert)


def _san(hosts: Sequence[str]) -> x509.SubjectAlternativeName:
    names: list[x509.GeneralName] = []
    for host in dict.fromkeys(hosts):
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    return x509.SubjectAlternativeName(names)


def issue(
    ca: Issued,
    role: str,
    robot_id: str,
    hosts: Sequence[str] = ("127.0.0.1", "localhost"),
    now: datetime.datetime | None = None,
) -> Issued:
    """A role's key and certificate, signed by ``ca``, good as TLS server and client.

    ``hosts`` go into the subject alternative names: the daemon's must name the host
    others connect to (Zenoh verifies it on connect); the others carry the same names,
    which costs nothing and lets any role listen on loopback if a deployment wants it.
    """
    now = now or datetime.datetime.now(datetime.UTC)
    key = ec.generate_private_key(ec.SECP256R1())
    ca_ski = ca.cert.extensions.get_extension_for_class(x509.SubjectKeyIdentifier).value
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name(role, robot_id)))
        .issuer_name(ca.cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=CERT_DAYS))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=False,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .add_extension(_san(hosts), critical=False)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_subject_key_identifier(ca_ski), critical=False
        )
        .sign(ca.key, hashes.SHA256())
    )
    return Issued(key, cert)


def cert_pem(cert: x509.Certificate) -> bytes:
    return cert.public_bytes(serialization.Encoding.PEM)


def key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


# ------------------------------------------------------------------ Zenoh configs


def _flip(flow: Flow) -> Flow:
    return "ingress" if flow == "egress" else "egress"


def _rules(
    prefix: str, grants: Sequence[Grant], robot_id: str, from_daemon: bool
) -> list[dict[str, Any]]:
    return [
        {
            "id": f"{prefix}{grant.name}",
            "permission": "allow",
            "flows": [_flip(grant.flow) if from_daemon else grant.flow],
            "messages": list(grant.messages),
            "key_exprs": [f"robots/{robot_id}/{key}" for key in grant.keys],
        }
        for grant in grants
    ]


def access_control(role: str, robot_id: str) -> dict[str, Any]:
    """Zenoh's ``access_control`` section for ``role``'s own peer, default deny.

    The daemon's lists every other role as a subject (by certificate common name) with
    that role's grants seen from the daemon; a role's lists the daemon as its only
    subject, with its own grants.
    """
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    others = [r for r in ROLES if r != "dms"] if role == "dms" else ["dms"]
    for other in others:
        grants = GRANTS[other] if role == "dms" else GRANTS[role]
        ids = _rules(f"{other}:", grants, robot_id, from_daemon=role == "dms")
        rules.extend(ids)
        subjects.append({"id": other, "cert_common_names": [common_name(other, robot_id)]})
        policies.append({"id": other, "subjects": [other], "rules": [rule["id"] for rule in ids]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def zenoh_config(role: str, robot_id: str, listen: str, directory: Path) -> dict[str, Any]:
    """The whole Zenoh config of ``role``: a peer on TLS only, mutual TLS, the ACL.

    The daemon listens on ``listen``; the others connect to it and listen nowhere.
    Scouting is off (multicast and gossip): a peer connects only where its file says,
    so a certificate holder cannot draw the others to itself.
    """
    directory = directory.resolve()
    cert, key = str(directory / f"{role}.pem"), str(directory / f"{role}.key")
    daemon = role == "dms"
    return {
        "mode": "peer",
        "listen": {"endpoints": [listen] if daemon else []},
        "connect": {"endpoints": [] if daemon else [listen]},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
        "transport": {
            "link": {
                "protocols": ["tls"],
                "tls": {
                    "root_ca_certificate": str(directory / "ca.pem"),
                    "enable_mtls": True,
                    "listen_private_key": key,
                    "listen_certificate": cert,
                    "connect_private_key": key,
                    "connect_certificate": cert,
                    "verify_name_on_connect": True,
                },
            }
        },
        "access_control": access_control(role, robot_id),
    }


# ------------------------------------------------------------------ files


def planned_files(directory: Path) -> list[Path]:
    """Every file :func:`init` writes, in order."""
    names = ["ca.pem", "ca.key"]
    for role in ROLES:
        names += [f"{role}.pem", f"{role}.key", f"{role}.json5"]
    return [directory / name for name in names]


def _refuse_links(paths: Sequence[Path]) -> None:
    """Refuse a symbolic link (or anything but a regular file) where a file goes.

    Whoever can write into the folder could plant ``ca.key -> /somewhere/else``; writing
    through it would put the CA key there. Checked before anything is written; the
    writes themselves never follow a link either (:func:`_write`).
    """
    for path in paths:
        if path.is_symlink():
            raise ConfigError(f"{path} is a symbolic link; refusing to write through it")
        if path.exists() and not path.is_file():
            raise ConfigError(f"{path} is not a regular file; refusing to replace it")


def _write(path: Path, data: bytes, private: bool) -> None:
    """Write ``data`` into a new file: an old one is removed first, and the new one is
    created exclusively (a link planted since the check makes it fail, not write through
    it), 0600 for a key from the start, never readable in between."""
    mode = 0o600 if private else 0o644
    path.unlink(missing_ok=True)  # removes a link itself, never what it points to
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, mode)
    except FileExistsError:
        raise ConfigError(f"{path} appeared while writing; refusing to write through it") from None
    with os.fdopen(fd, "wb") as out:
        os.fchmod(out.fileno(), mode)  # O_CREAT's mode passes the umask
        out.write(data)


def init(
    directory: Path, robot_id: str, listen: str = DEFAULT_LISTEN, force: bool = False
) -> list[Path]:
    """Write the CA, a certificate, key and Zenoh config per role into ``directory``.

    Refuses (ConfigError, nothing written) a bad robot id or endpoint, a symbolic link
    where one of the files goes, and a directory that already holds any of the files
    unless ``force``: overwriting a CA silently would lock every deployed program out.
    """
    check_robot_id(robot_id)
    host, _port = parse_listen(listen)
    paths = planned_files(directory)
    _refuse_links(paths)
    existing = [p.name for p in paths if p.exists()]
    if existing and not force:
        raise ConfigError(
            f"{directory} already holds {', '.join(existing[:3])}"
            f"{'...' if len(existing) > 3 else ''}; use --force to replace them"
        )
    try:
        directory.mkdir(parents=True, exist_ok=True)
        if not os.access(directory, os.W_OK | os.X_OK):
            raise PermissionError(f"{directory}: not writable")
    except OSError as error:
        raise ConfigError(f"cannot write into {directory}: {error.strerror or error}") from None
    ca = make_ca(robot_id)
    hosts = [host, "127.0.0.1", "localhost"]
    try:
        _write(directory / "ca.pem", cert_pem(ca.cert), private=False)
        _write(directory / "ca.key", key_pem(ca.key), private=True)
        for role in ROLES:
            issued = issue(ca, role, robot_id, hosts)
            _write(directory / f"{role}.pem", cert_pem(issued.cert), private=False)
            _write(directory / f"{role}.key", key_pem(issued.key), private=True)
            config = zenoh_config(role, robot_id, listen, directory)
            text = (
                f"// Zenoh config of the {role!r} role of robot {robot_id!r}: mutual TLS and\n"
                "// access control, written by `dms secure init` (docs/security.md).\n"
                + json.dumps(config, indent=2)
                + "\n"
            )
            _write(directory / f"{role}.json5", text.encode(), private=False)
    except OSError as error:
        raise ConfigError(f"cannot write into {directory}: {error.strerror or error}") from None
    return paths


def _load_ca(directory: Path) -> Issued:
    try:
        cert = x509.load_pem_x509_certificate((directory / "ca.pem").read_bytes())
        key = serialization.load_pem_private_key((directory / "ca.key").read_bytes(), None)
    except OSError as error:
        raise ConfigError(
            f"cannot read the CA in {directory}: {error.strerror or error}"
            " (renew needs ca.pem and ca.key from `dms secure init`)"
        ) from None
    except ValueError as error:
        raise ConfigError(f"the CA in {directory} is not readable: {error}") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise ConfigError(f"{directory / 'ca.key'} is not the EC key `dms secure init` writes")
    return Issued(key, cert)


def renew(directory: Path, role: str) -> list[Path]:
    """Replace ``role``'s key and certificate with new ones from the same CA.

    For a leaked key or an expiring certificate: the role's common name and host names
    are kept, so no config changes and every other program keeps working; the old
    certificate stays valid until it expires (Zenoh has no revocation list), which is why
    a leaked *CA* key means ``init --force`` and redeploying every file instead.
    """
    if role not in ROLES:
        raise ConfigError(f"unknown role {role!r}: one of {', '.join(ROLES)}")
    cert_path, key_path = directory / f"{role}.pem", directory / f"{role}.key"
    _refuse_links([cert_path, key_path])
    ca = _load_ca(directory)
    try:
        old = x509.load_pem_x509_certificate(cert_path.read_bytes())
    except (OSError, ValueError) as error:
        raise ConfigError(f"cannot read {cert_path}: {error}") from None
    cn = old.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    robot_id = str(cn[0].value).split(".")[1] if cn and str(cn[0].value).count(".") == 2 else ""
    if common_name(role, robot_id) != (cn[0].value if cn else None):
        raise ConfigError(f"{cert_path} was not written by `dms secure init` for role {role}")
    san = old.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    hosts = [str(ip) for ip in san.get_values_for_type(x509.IPAddress)]
    hosts += san.get_values_for_type(x509.DNSName)
    issued = issue(ca, role, robot_id, hosts)
    try:
        _write(key_path, key_pem(issued.key), private=True)
        _write(cert_path, cert_pem(issued.cert), private=False)
    except OSError as error:
        raise ConfigError(f"cannot write into {directory}: {error.strerror or error}") from None
    return [cert_path, key_path]
