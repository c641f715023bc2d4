"""The link against a server of the model on loopback: windows read once, in order; a jump of
Sequence counted as missed windows; a server that restarts; a server without the model."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from runtime_cases import ServerThread, free_port

from twin_cosim.runtime.link import LinkLost, LinkRefused, MachineLink, Missed, Notice, Received


def arrays(value: float, n: int = 64) -> dict[str, np.ndarray]:
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
    first = server.publish(arrays(1.0))  # before the link connects: read as the first
    link = MachineLink(server.server.endpoint, "X", poll_s=0.1)

    async def scenario() -> list:
        reading = asyncio.ensure_future(take(link, 3))
        await asyncio.sleep(1.0)
        await asyncio.to_thread(server.publish, arrays(2.0))
        await asyncio.sleep(1.0)
        for value in (3.0, 4.0, 5.0):  # the first two are overwritten before the next read
            server.call(server.server.publish(arrays(value)))
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
    server.publish(arrays(1.0))
    link = MachineLink(server.server.endpoint, "X", poll_s=0.1, reconnect_timeout_s=20.0)

    async def scenario() -> list:
        reading = asyncio.ensure_future(take(link, 2, timeout=40.0))
        await asyncio.sleep(1.0)
        await asyncio.to_thread(server.restart)  # the link loses its connection
        await asyncio.sleep(1.0)
        await asyncio.to_thread(server.publish, arrays(2.0))
        await asyncio.to_thread(server.publish, arrays(3.0))
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
