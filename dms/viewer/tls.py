"""HTTPS for the pages (``dms view``, ``dms studio``), and the rule that a page leaves
loopback only over it.

On loopback nobody else sees the traffic. On another address the studio's token, the
agenda's texts and every write would cross the network in the clear, so a ``--host``
that is not a loopback address is refused unless ``--tls-cert`` and ``--tls-key`` are
given. The files are checked when the command starts, each fault in one line naming
the file: a browser would only say "connection failed" later.
"""

from __future__ import annotations

import ipaddress
import ssl
from pathlib import Path

from dms.kernel.errors import ConfigError

MAKE_THEM = "`dms secure init` writes them"
"""Where a certificate comes from, said in the refusals (docs/viewer.md says how)."""


def is_loopback(address: str) -> bool:
    """Whether ``address``, an IP address as a socket reports it, is a loopback one."""
    try:
        return ipaddress.ip_address(address.split("%", 1)[0]).is_loopback
    except ValueError:
        return False


def refuse_clear_text(page: str, host: str, address: str) -> None:
    """ConfigError unless ``address`` (what ``--host`` resolved to) is loopback: called
    before binding, when no TLS files were given."""
    if not is_loopback(address):
        raise ConfigError(
            f"--host {host or address} serves the {page} to other machines: give --tls-cert "
            f"FILE and --tls-key FILE ({MAKE_THEM}), or keep the default --host 127.0.0.1"
        )


def server_context(cert: Path | None, key: Path | None) -> ssl.SSLContext | None:
    """The TLS context of a page served with ``--tls-cert`` and ``--tls-key`` (TLS 1.2 at
    least); None when neither is given. A missing, unreadable or mismatched file is a
    ConfigError naming it."""
    if cert is None and key is None:
        return None
    if cert is None or key is None:
        raise ConfigError("--tls-cert and --tls-key go together: give both, or neither")
    _check_files(cert, key)
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        context.load_cert_chain(cert, key)
    except ssl.SSLError as error:
        raise ConfigError(
            f"--tls-key {key} is not the key of --tls-cert {cert} "
            f"({error.reason or error.strerror or error})"
        ) from None
    return context


def _check_files(cert: Path, key: Path) -> None:
    """Each file read and parsed, so that a fault names the file it is in (OpenSSL's
    own message is "PEM lib" for all of them)."""
    from cryptography import x509
    from cryptography.exceptions import UnsupportedAlgorithm
    from cryptography.hazmat.primitives import serialization

    cert_text, key_text = _read("--tls-cert", cert), _read("--tls-key", key)
    try:
        x509.load_pem_x509_certificate(cert_text)
    except ValueError:
        raise ConfigError(f"--tls-cert {cert}: not a PEM certificate") from None
    try:
        serialization.load_pem_private_key(key_text, password=None)
    except TypeError:  # what cryptography raises for a key with a passphrase
        raise ConfigError(
            f"--tls-key {key}: the key has a passphrase; give one without "
            "(openssl pkey -in KEY -out PLAIN.key)"
        ) from None
    except (ValueError, UnsupportedAlgorithm):
        raise ConfigError(f"--tls-key {key}: not a PEM private key") from None


def _read(option: str, path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as error:
        raise ConfigError(f"{option} {path}: {error.strerror or error}") from None
