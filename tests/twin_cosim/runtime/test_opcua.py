"""The OPC UA link: the information model's window (what a client accepts, and what it refuses,
naming it), the security, the client.

Security as a CNC's server demands it: Basic256Sha256 SignAndEncrypt and a user; a client
with the certificate, key and user connects, one without them is refused with a clear error.
Certificates and keys are made here, in a temporary folder.

The link against a server of the model on loopback: windows read once, in order; a jump of
Sequence counted as missed windows; a server that restarts; a server without the model.
"""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest
from runtime_cases import ServerThread, free_port

from twin_cosim.runtime.opcua import (
    CLIENT_URI,
    SERVER_URI,
    LinkLost,
    LinkRefused,
    MachineLink,
    Missed,
    Notice,
    Received,
    Security,
    SecurityError,
    WindowError,
    application_uri,
    check_period,
    security_from,
    self_signed,
    sequence_gap,
    window_of,
)


def window_arrays(n: int = 100, period: float = 250e-6) -> dict[str, list[float]]:
    t = 3.0 + np.arange(n) * period  # the window's own clock need not start at 0
    return {
        "time": t.tolist(),
        "position_reference": np.linspace(0, 1e-3, n).tolist(),
        "position": np.linspace(0, 1e-3, n).tolist(),
        "current": np.zeros(n).tolist(),
    }


def test_a_window_without_motor_speed_is_read_with_its_period_and_duration() -> None:
    window = window_of(5, window_arrays(), "window 0 (Sequence 5)")
    assert window.motor_speed is None and window.samples == 100
    assert math.isclose(window.period, 250e-6) and math.isclose(window.duration, 0.025)
    assert set(window.arrays()) == {"time", "position_reference", "position", "current"}


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (lambda a: a.update(current=a["current"][:-1]), "unequal length"),
        (lambda a: a["position"].__setitem__(7, float("nan")), "position holds 1 NaN"),
        (lambda a: a.pop("current"), "no array 'current'"),
        (lambda a: a["time"].__setitem__(50, a["time"][50] + 1e-4), "regular step"),
        (lambda a: a.update(motor_speed=[0.0] * 99), "unequal length"),
    ],
)
def test_a_bad_window_is_refused_naming_the_window_and_the_array(change, expected) -> None:
    data = window_arrays()
    change(data)
    with pytest.raises(WindowError, match=expected) as raised:
        window_of(9, data, "window 4 (Sequence 9)")
    assert "window 4 (Sequence 9)" in str(raised.value)


def test_a_window_not_sampled_at_the_position_loop_period_is_refused() -> None:
    window = window_of(1, window_arrays(period=1e-3), "window 0")
    with pytest.raises(WindowError, match="1000 us.*250 us"):
        check_period(window, 250e-6, "window 0")
    check_period(window_of(1, window_arrays(), "window 0"), 250e-6, "window 0")


def test_sequence_gaps_count_the_windows_between_and_wrap_as_a_uint32() -> None:
    assert sequence_gap(4, 5) == 0
    assert sequence_gap(4, 8) == 3
    assert sequence_gap(2**32 - 1, 0) == 0
    assert sequence_gap(2**32 - 2, 1) == 2


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


def published_arrays(value: float, n: int = 64) -> dict[str, np.ndarray]:
    t = np.arange(n) * 250e-6
    return {"time": t, "position_reference": t * 0, "position": t * 0 + value, "current": t * 0}


async def take(link: MachineLink, count: int, timeout: float = 15.0) -> list:
    events = []
    stream = link.events()

    async def gather() -> None:
        async for event in stream:
            events.append(event)
            if sum(isinstance(e, Received) for e in events) >= count:
                return

    try:
        await asyncio.wait_for(gather(), timeout)
    finally:
        await stream.aclose()
    return events


@pytest.fixture(scope="module")
def server():
    """One server of the model for the module (a server takes seconds to start)."""
    running = ServerThread(free_port(), with_motor_speed=False)
    yield running
    running.close()


def test_windows_are_read_once_each_and_jumps_are_counted_as_missed(server) -> None:
    first = server.publish(published_arrays(1.0))  # before the link connects: read as the first
    link = MachineLink(server.server.endpoint, "X", poll_s=0.1)

    async def scenario() -> list:
        reading = asyncio.ensure_future(take(link, 3))
        await asyncio.sleep(1.0)
        await asyncio.to_thread(server.publish, published_arrays(2.0))
        await asyncio.sleep(1.0)
        for value in (3.0, 4.0, 5.0):  # the first two are overwritten before the next read
            server.call(server.server.publish(published_arrays(value)))
        return await reading

    events = asyncio.run(scenario())
    received = [e for e in events if isinstance(e, Received)]
    assert [e.sequence - first for e in received] == [0, 1, 4]
    assert [e.arrays["position"][0] for e in received] == [1.0, 2.0, 5.0]
    assert "motor_speed" not in received[0].arrays
    missed = [e for e in events if isinstance(e, Missed)]
    assert [(m.count, m.after - first, m.before - first) for m in missed] == [(2, 1, 4)]
    assert link.missed == 2


def test_a_server_that_goes_away_and_comes_back_is_followed_without_reading_twice() -> None:
    server = ServerThread(free_port())
    server.publish(published_arrays(1.0))
    link = MachineLink(server.server.endpoint, "X", poll_s=0.1, reconnect_timeout_s=20.0)

    async def scenario() -> list:
        reading = asyncio.ensure_future(take(link, 2, timeout=40.0))
        await asyncio.sleep(1.0)
        await asyncio.to_thread(server.restart)  # the link loses its connection
        await asyncio.sleep(1.0)
        await asyncio.to_thread(server.publish, published_arrays(2.0))
        await asyncio.to_thread(server.publish, published_arrays(3.0))
        return await reading

    try:
        events = asyncio.run(scenario())
    finally:
        server.close()
    kinds = [e.kind for e in events if isinstance(e, Notice)]
    assert kinds[0] == "connected" and "lost" in kinds and "restored" in kinds
    received = [e.sequence for e in events if isinstance(e, Received)]
    assert len(received) == 2 and received[1] > received[0]  # none read twice


def test_a_fall_of_sequence_is_a_restart_and_not_a_window_read_twice() -> None:
    link = MachineLink("opc.tcp://127.0.0.1:1", "X")
    link.last = 57
    events = link._sequence_events(3)
    assert events[0].kind == "restarted" and events[1] == Missed(2, 0, 3)
    link.last = 2**32 - 1
    assert link._sequence_events(0) == []  # the UInt32 wrapped: the next window


def test_a_server_without_the_axis_or_the_model_is_refused_by_name(server) -> None:
    with pytest.raises(LinkRefused, match=r"no Objects/Machine/Y/Trace.*axes found: X"):
        asyncio.run(take(MachineLink(server.server.endpoint, "Y", poll_s=0.1), 1))
    with pytest.raises(LinkRefused, match="opc.tcp://HOST:PORT"):
        MachineLink("http://127.0.0.1:4840", "X")


def test_no_server_is_given_up_after_the_reconnection_timeout() -> None:
    link = MachineLink(f"opc.tcp://127.0.0.1:{free_port()}", "X", reconnect_timeout_s=1.0)
    with pytest.raises(LinkLost, match="could not reach"):
        asyncio.run(take(link, 1, timeout=20.0))
