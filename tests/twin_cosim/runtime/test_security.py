"""Security as a CNC's server demands it: Basic256Sha256 SignAndEncrypt and a user; a client
with the certificate, key and user connects, one without them is refused with a clear error.
Certificates and keys are made here, in a temporary folder."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from runtime_cases import ServerThread, free_port

from twin_cosim.runtime.link import LinkRefused, MachineLink, Received
from twin_cosim.runtime.security import (
    CLIENT_URI,
    SERVER_URI,
    Security,
    SecurityError,
    application_uri,
    security_from,
    self_signed,
)


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    """A server demanding SignAndEncrypt and user ``operator``, and a client's certificate."""
    folder = tmp_path_factory.mktemp("pki")
    server_certificate, server_key = self_signed(folder, "server", SERVER_URI, server=True)
    client_certificate, client_key = self_signed(folder, "client", CLIENT_URI, server=False)
    demands = Security("SignAndEncrypt", server_certificate, server_key, "operator", "s3cret")
    server = ServerThread(free_port(), security=demands)
    t = np.arange(32) * 250e-6
    server.publish({"time": t, "position_reference": t, "position": t, "current": t})
    yield server, client_certificate, client_key
    server.close()


async def first(link: MachineLink):
    stream = link.events()
    try:
        async for event in stream:
            if isinstance(event, Received):
                return event
    finally:
        await stream.aclose()


def test_a_client_with_certificate_key_and_user_reads_windows(secured) -> None:
    server, certificate, key = secured
    security = Security("SignAndEncrypt", certificate, key, "operator", "s3cret")
    link = MachineLink(server.server.endpoint, "X", security, poll_s=0.1)
    window = asyncio.run(asyncio.wait_for(first(link), 30.0))
    assert window.sequence == 1 and len(window.arrays["time"]) == 32


@pytest.mark.parametrize(
    ("security", "expected"),
    [
        (None, "refused the connection.*security policy"),
        ("no user", "refused the connection.*TWIN_OPCUA_USER"),
        ("wrong password", "refused the connection.*TWIN_OPCUA_USER"),
    ],
)
def test_a_client_without_what_the_server_demands_is_refused(secured, security, expected) -> None:
    server, certificate, key = secured
    chosen = {
        None: Security(),
        "no user": Security("SignAndEncrypt", certificate, key),
        "wrong password": Security("SignAndEncrypt", certificate, key, "operator", "guess"),
    }[security]
    link = MachineLink(server.server.endpoint, "X", chosen, poll_s=0.1, reconnect_timeout_s=5.0)
    with pytest.raises(LinkRefused, match=expected):
        asyncio.run(asyncio.wait_for(first(link), 30.0))


def test_settings_come_from_the_options_and_the_password_from_the_environment(tmp_path) -> None:
    certificate, key = self_signed(tmp_path, "client", CLIENT_URI, server=False)
    assert application_uri(certificate) == CLIENT_URI
    environ = {"TWIN_OPCUA_USER": "operator", "TWIN_OPCUA_PASSWORD": "s3cret"}
    security = security_from("Sign", str(certificate), str(key), environ)
    assert security.user == "operator" and "s3cret" not in repr(security)
    with pytest.raises(SecurityError, match="needs --certificate"):
        security_from("SignAndEncrypt", None, str(key), {})
    with pytest.raises(SecurityError, match="need --security"):
        security_from("None", str(certificate), None, {})
    with pytest.raises(SecurityError, match="TWIN_OPCUA_USER is not"):
        security_from("None", None, None, {"TWIN_OPCUA_PASSWORD": "x"})
