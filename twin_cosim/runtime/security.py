"""Security of the OPC UA link as a CNC's server demands it: the Basic256Sha256 policy with Sign
or SignAndEncrypt, an application certificate and key, and a user name and password.

The password is read from the environment only (:data:`USER_ENV`, :data:`PASSWORD_ENV`), never
from the command line or a log. :func:`self_signed` makes a certificate and key (tests make them
at run time in a temporary folder; no key is ever committed).
"""

from __future__ import annotations

import os
import socket
from dataclasses import dataclass
from pathlib import Path

USER_ENV = "TWIN_OPCUA_USER"
PASSWORD_ENV = "TWIN_OPCUA_PASSWORD"
MODES = ("None", "Sign", "SignAndEncrypt")
CLIENT_URI = "urn:twin-cosim:watch"
SERVER_URI = "urn:twin-cosim:serve"


class SecurityError(ValueError):
    """Security settings that cannot work (the message names the option or variable)."""


@dataclass(frozen=True)
class Security:
    """How to secure a connection.

    Attributes
    ----------
    mode : str
        ``None`` (no security, loopback tests), ``Sign`` or ``SignAndEncrypt`` (Basic256Sha256).
    certificate, private_key : Path or None
        The application's certificate (DER or PEM) and private key (PEM).
    user, password : str or None
        The user name and password (from the environment).
    """

    mode: str = "None"
    certificate: Path | None = None
    private_key: Path | None = None
    user: str | None = None
    password: str | None = None

    @property
    def secured(self) -> bool:
        """Whether the channel is signed (and maybe encrypted)."""
        return self.mode != "None"

    def __repr__(self) -> str:  # never show the password
        return (
            f"Security(mode={self.mode!r}, certificate={self.certificate}, "
            f"private_key={self.private_key}, user={self.user!r})"
        )


def security_from(
    mode: str, certificate: str | None, private_key: str | None, environ: dict | None = None
) -> Security:
    """Security settings from the options and the environment (user and password).

    Raises
    ------
    SecurityError
        An unknown mode; Sign or SignAndEncrypt without a readable certificate and key; a
        certificate or key given without a security mode; a password without a user.
    """
    environ = os.environ if environ is None else environ
    if mode not in MODES:
        raise SecurityError(f"--security {mode!r}: expected one of {', '.join(MODES)}")
    files = {"--certificate": certificate, "--private-key": private_key}
    if mode == "None" and any(files.values()):
        raise SecurityError(
            "--certificate and --private-key need --security Sign or SignAndEncrypt"
        )
    if mode != "None":
        for option, value in files.items():
            if not value:
                raise SecurityError(f"--security {mode} needs {option} FILE")
            if not Path(value).is_file():
                raise SecurityError(f"{option} {value}: no such file")
    user, password = environ.get(USER_ENV) or None, environ.get(PASSWORD_ENV) or None
    if password and not user:
        raise SecurityError(f"${PASSWORD_ENV} is set but ${USER_ENV} is not")
    return Security(
        mode,
        Path(certificate) if certificate else None,
        Path(private_key) if private_key else None,
        user,
        password,
    )


def self_signed(folder: Path, name: str, application_uri: str, server: bool) -> tuple[Path, Path]:
    """A self-signed application certificate (DER) and its key (PEM) in ``folder``, for
    127.0.0.1 and this host; ``server`` for a server's use, else a client's.

    Returns
    -------
    (Path, Path)
        The certificate and the key.
    """
    import ipaddress

    from asyncua.crypto.cert_gen import (
        dump_private_key_as_pem,
        generate_private_key,
        generate_self_signed_app_certificate,
    )
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization
    from cryptography.x509.oid import ExtendedKeyUsageOID

    key = generate_private_key()
    names = [
        x509.UniformResourceIdentifier(application_uri),
        x509.DNSName(socket.gethostname()),
        x509.DNSName("localhost"),
        x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
    ]
    use = [ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH]
    certificate = generate_self_signed_app_certificate(key, name, {}, names, use)
    folder.mkdir(parents=True, exist_ok=True)
    certificate_path, key_path = folder / f"{name}.der", folder / f"{name}.pem"
    certificate_path.write_bytes(certificate.public_bytes(serialization.Encoding.DER))
    key_path.write_bytes(dump_private_key_as_pem(key))
    key_path.chmod(0o600)
    return certificate_path, key_path


def application_uri(certificate: Path) -> str | None:
    """The application URI in a certificate's subject alternative names (None when absent)."""
    from cryptography import x509

    data = certificate.read_bytes()
    try:
        loaded = x509.load_der_x509_certificate(data)
    except ValueError:
        loaded = x509.load_pem_x509_certificate(data)
    try:
        names = loaded.extensions.get_extension_for_class(x509.SubjectAlternativeName)
    except x509.ExtensionNotFound:
        return None
    uris = names.value.get_values_for_type(x509.UniformResourceIdentifier)
    return uris[0] if uris else None
