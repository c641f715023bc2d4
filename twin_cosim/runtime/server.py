"""An OPC UA server of the information model (:mod:`twin_cosim.runtime.information_model`) on
127.0.0.1, and the virtual machine behind it (``twin serve``).

:class:`MachineServer` holds the model's nodes and publishes a window: it writes the arrays, then
increments ``Sequence``, so that a client that reads after the increment reads that window. The
twin's namespace (``Twin``) is writable, as the twin writes its alarms there. :func:`serve_machine`
publishes the virtual machine's windows one after the other (each computed in a process of its
own while the server answers: a replay in a thread would hold the interpreter's lock and starve
the server's loop, which clients see as a lost connection), a window lasting its duration over
``speed``.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from twin_cosim.runtime.information_model import (
    ARRAYS,
    MACHINE,
    MACHINE_NAMESPACE,
    SEQUENCE,
    SEQUENCE_MODULUS,
    TRACE,
    TWIN,
    TWIN_NAMESPACE,
    TWIN_VARIABLES,
    Window,
)
from twin_cosim.runtime.security import SERVER_URI, Security

LOOPBACK = "127.0.0.1"


def endpoint_of(port: int) -> str:
    """The endpoint URL of a server on this machine's loopback at ``port``."""
    return f"opc.tcp://{LOOPBACK}:{port}"


class _Users:
    """Lets in the one user of the server's security settings (asyncua's user manager)."""

    def __init__(self, user: str, password: str) -> None:
        self._user, self._password = user, password

    def get_user(self, iserver: Any, username=None, password=None, certificate=None):
        from asyncua.crypto.permission_rules import User, UserRole

        if username == self._user and password == self._password:
            return User(role=UserRole.User, name=username)
        return None


class MachineServer:
    """The server of one machine: its axes' ``Trace`` objects and the twin's namespace.

    Parameters
    ----------
    port
        TCP port on 127.0.0.1.
    axes
        The axes' names.
    security
        None: no security; else the policy the server demands (Basic256Sha256 with the mode),
        its certificate and key, and the one user and password it lets in.
    with_motor_speed
        Whether the traces hold ``motor_speed``.
    """

    def __init__(
        self,
        port: int,
        axes: tuple[str, ...] = ("X",),
        security: Security | None = None,
        with_motor_speed: bool = True,
    ) -> None:
        self.port = port
        self.axes = axes
        self.security = security or Security()
        self.with_motor_speed = with_motor_speed
        self.sequence = 0
        self._server: Any = None
        self._nodes: dict[str, dict[str, Any]] = {}
        self.twin_nodes: dict[str, Any] = {}

    @property
    def endpoint(self) -> str:
        """The endpoint URL."""
        return endpoint_of(self.port)

    async def start(self) -> None:
        """Build the address space (the first time) and listen on 127.0.0.1; after
        :meth:`stop`, listen again with the same address space and Sequence."""
        from asyncua import Server, ua

        if self._server is not None:
            await self._server.start()
            return

        logging.getLogger("asyncua").setLevel(logging.ERROR)
        security = self.security
        server = Server(
            user_manager=_Users(security.user, security.password or "") if security.user else None
        )
        await server.init()
        server.set_endpoint(self.endpoint)
        server.set_server_name("twin-cosim virtual machine")
        await server.set_application_uri(SERVER_URI)
        if security.secured:
            policy = {
                "Sign": ua.SecurityPolicyType.Basic256Sha256_Sign,
                "SignAndEncrypt": ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
            }[security.mode]
            server.set_security_policy([policy])
            await server.load_certificate(str(security.certificate))
            await server.load_private_key(str(security.private_key))
        else:
            server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        if security.user:
            server.set_identity_tokens([ua.UserNameIdentityToken])
        machine_ns = await server.register_namespace(MACHINE_NAMESPACE)
        twin_ns = await server.register_namespace(TWIN_NAMESPACE)
        machine = await server.nodes.objects.add_object(machine_ns, MACHINE)
        arrays = [n for n in ARRAYS if n != "motor_speed" or self.with_motor_speed]
        for axis in self.axes:
            axis_node = await machine.add_object(machine_ns, axis)
            trace = await axis_node.add_object(machine_ns, TRACE)
            nodes = {}
            for name in arrays:
                nodes[name] = await trace.add_variable(
                    machine_ns, name, ua.Variant([], ua.VariantType.Double)
                )
            nodes[SEQUENCE] = await trace.add_variable(
                machine_ns, SEQUENCE, ua.Variant(0, ua.VariantType.UInt32)
            )
            self._nodes[axis] = nodes
        twin = await server.nodes.objects.add_object(twin_ns, TWIN)
        initial = {"UInt32": 0, "Double": 0.0, "String": ""}
        for name, kind in TWIN_VARIABLES.items():
            node = await twin.add_variable(
                twin_ns, name, ua.Variant(initial[kind], getattr(ua.VariantType, kind))
            )
            await node.set_writable()
            self.twin_nodes[name] = node
        await server.start()
        self._server = server

    async def stop(self) -> None:
        """Stop listening and drop every connection at once (clients see it go): a connection
        is aborted, not closed, so that the stop never waits for a slow client to take the
        data still buffered for it (asyncua's stop waits for every connection to end); the
        listening socket is closed first, so that a client reconnecting at once is not let in
        while the stop waits."""
        if self._server is not None:
            listener = getattr(self._server.bserver, "_server", None)  # asyncio's server
            if listener is not None:
                listener.close()
            for transport in list(self._server.iserver.asyncio_transports):
                transport.abort()
            await self._server.stop()

    async def publish(
        self, arrays: dict[str, Any], axis: str = "X", sequence: int | None = None
    ) -> int:
        """Write one window's arrays, then increment ``Sequence`` (or set it to ``sequence``);
        the new Sequence.

        ``arrays``: browse name -> values (a window's arrays; tests may give unequal lengths or
        NaN to try a client's checks).
        """
        from asyncua import ua

        nodes = self._nodes[axis]
        for name, values in arrays.items():
            if name in nodes:
                data = np.asarray(values, dtype=np.float64).tolist()
                await nodes[name].write_value(ua.Variant(data, ua.VariantType.Double))
        self.sequence = (self.sequence + 1) % SEQUENCE_MODULUS if sequence is None else sequence
        await nodes[SEQUENCE].write_value(ua.Variant(self.sequence, ua.VariantType.UInt32))
        return self.sequence

    async def twin_value(self, name: str) -> Any:
        """A value the twin wrote into its namespace."""
        return await self.twin_nodes[name].read_value()


async def serve_machine(
    server: MachineServer,
    make_window: Callable[[int], Window],
    windows: int | None,
    speed: float,
    first: int = 0,
    announce: Callable[[str], None] | None = None,
) -> int:
    """Publish windows ``first``, ``first + 1``, ... (``windows`` of them; None: until
    cancelled), each when its duration over ``speed`` has passed since the one before (or as
    soon as it is computed, when that takes longer); the windows published.

    ``make_window(k)`` computes window k (picklable: it runs in a worker process while the
    server answers).
    """
    from concurrent.futures import ProcessPoolExecutor

    loop = asyncio.get_running_loop()
    published = 0
    due = time.monotonic()
    k = first
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=context) as worker:
        next_window = loop.run_in_executor(worker, make_window, k)
        while windows is None or published < windows:
            window = await next_window
            due += window.duration / speed
            k += 1
            if windows is None or published + 1 < windows:
                next_window = loop.run_in_executor(worker, make_window, k)
            await asyncio.sleep(max(0.0, due - time.monotonic()))
            sequence = await server.publish(window.arrays())
            published += 1
            if announce:
                announce(
                    f"window {k - 1} published (Sequence {sequence}, {window.samples} samples)"
                )
    return published
