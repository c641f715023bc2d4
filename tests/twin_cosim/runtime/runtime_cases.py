"""What the runtime twin's tests share: a short production cycle (a move out and back with a
reversal while moving, 1.3 s), its scenario file, and a virtual machine running it."""

from __future__ import annotations

from pathlib import Path

from scenario_texts import scenario_text

from twin_cosim.runtime.virtual_machine import Drift, VirtualMachine, draw_machine
from twin_cosim.scenario import Scenario, resolve_scenario


def cycle_file(folder: Path) -> Path:
    """The cycle's scenario file in ``folder``: dwell, 20 mm/s out, back, stop, dwell."""
    path = folder / "cycle.yaml"
    text = scenario_text("cycle", speed=0.02, acceleration=0.2, move=0.4, stop=0.2, dwell=0.15)
    path.write_text(text)
    return path


def cycle(folder: Path) -> Scenario:
    """The cycle's scenario."""
    return resolve_scenario(cycle_file(folder))


def machine(
    scenario: Scenario, drifts: list[Drift] | None = None, start: int = 0, seed: int = 3
) -> VirtualMachine:
    """The cycle's virtual machine: 2 % calibration error, 20 nm and 5 mA of noise."""
    return draw_machine(
        scenario, str(scenario.plant_fmu()), [], drifts or [], start, perturb=0.02, seed=seed
    )


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class ServerThread:
    """A :class:`~twin_cosim.runtime.opcua.MachineServer` on its own event loop in a thread,
    driven by the test: publish windows, stop, start again on the same port."""

    def __init__(self, port: int, security=None, with_motor_speed: bool = True) -> None:
        import asyncio
        import threading

        from twin_cosim.runtime.opcua import MachineServer

        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.server = MachineServer(port, security=security, with_motor_speed=with_motor_speed)
        self.call(self.server.start())

    def call(self, coroutine, timeout: float = 20.0):
        import asyncio

        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(timeout)

    def publish(self, arrays) -> int:
        return self.call(self.server.publish(arrays))

    def publish_burst(self, windows) -> int:
        """Publish windows one after the other in one go of the server's loop: a client reads
        at most the last (the others are missed); the last Sequence."""

        async def burst() -> int:
            for arrays in windows:
                sequence = await self.server.publish(arrays)
            return sequence

        return self.call(burst())

    def twin_value(self, name: str):
        return self.call(self.server.twin_value(name))

    def restart(self) -> None:
        """Stop, then listen again on the same port (Sequence carries on)."""
        self.call(self.server.stop())
        self.call(self.server.start())

    def close(self) -> None:
        self.call(self.server.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5.0)
