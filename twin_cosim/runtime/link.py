"""The twin's OPC UA link to the machine: connect (with the security a CNC asks for), find the
model by its namespace URI and browse names, follow ``Sequence``, read each window once, count
the windows missed, and survive the server going away.

How a window is found. The link subscribes to ``Sequence`` (data-change notifications, the
queue of one value: only the latest matters) and also polls it every ``poll_s`` seconds, so
that a server whose notifications stop (or never come) is still followed; either way it reads
``Sequence`` alone, and when that changed, the window's arrays together with ``Sequence`` in
one Read request: the window is labelled by the Sequence read with its arrays. A Sequence that
did not change is never read again; one that jumps by more than one counts the windows
between as missed; one that falls (the server restarted, or the UInt32 wrapped) starts the
count anew from it and says so. A window being written while it is read cannot be told by the
model (it has no lock): the link reads at once after each change, and the window's own checks
(equal lengths, finite values, regular time) catch a torn read that breaks them.

Reconnection. A read that fails, a closed connection or a subscription that dies makes the
link reconnect with exponential backoff (:data:`FIRST_BACKOFF_S` doubling up to
:data:`MAX_BACKOFF_S`), for at most ``reconnect_timeout_s`` seconds without a connection
(then :class:`LinkLost`); after a reconnection the Sequence tells what was missed. A server
that refuses the client (security policy, certificate, user) raises :class:`LinkRefused` at
once.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import Any

from twin_cosim.runtime.information_model import (
    MACHINE,
    MACHINE_NAMESPACE,
    OPTIONAL_ARRAYS,
    REQUIRED_ARRAYS,
    SEQUENCE,
    SEQUENCE_MODULUS,
    TRACE,
    TWIN,
    TWIN_NAMESPACE,
    TWIN_VARIABLES,
)
from twin_cosim.runtime.security import CLIENT_URI, Security, application_uri

FIRST_BACKOFF_S = 0.2
MAX_BACKOFF_S = 5.0
REQUEST_TIMEOUT_S = 10.0
# Status codes by which a server refuses a client: a user error, not a lost connection.
REFUSALS = (
    "BadSecurityPolicyRejected",
    "BadSecurityModeRejected",
    "BadSecurityChecksFailed",
    "BadCertificateInvalid",
    "BadCertificateUntrusted",
    "BadCertificateUriInvalid",
    "BadIdentityTokenInvalid",
    "BadIdentityTokenRejected",
    "BadUserAccessDenied",
)


class LinkRefused(ValueError):
    """The server refuses this client, or does not hold the model: a user error."""


class LinkLost(RuntimeError):
    """No connection for longer than the reconnection timeout."""


@dataclass(frozen=True)
class Received:
    """A window read off the server: its Sequence and arrays (browse name -> values)."""

    sequence: int
    arrays: dict[str, list[float]]
    received_at: float  # time.time(), s


@dataclass(frozen=True)
class Missed:
    """Windows the server published that the link never read."""

    count: int
    after: int | None  # the Sequence read before them (None: before the first read)
    before: int  # the Sequence read after them


@dataclass(frozen=True)
class Notice:
    """Something the link says (connection lost or restored, server restarted)."""

    kind: str  # "connected", "lost", "restored", "restarted", "twin_namespace"
    text: str


LinkEvent = Received | Missed | Notice


class _Wake:
    """Data-change handler of the subscription: sets the event the link waits on."""

    def __init__(self, event: asyncio.Event) -> None:
        self.event = event
        self.notifications = 0

    def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
        self.notifications += 1
        self.event.set()

    def status_change_notification(self, status: Any) -> None:
        self.event.set()  # a dying subscription: the next read finds out


def _refusal(exc: BaseException) -> str | None:
    """The refusal's status name when ``exc`` is the server refusing this client (an endpoint
    list without the client's security policy counts as BadSecurityPolicyRejected)."""
    text = f"{type(exc).__name__} {exc}"
    if "No matching endpoints" in text:
        return "BadSecurityPolicyRejected: no endpoint with this security"
    return next((code for code in REFUSALS if code in text), None)


class MachineLink:
    """The link to one axis of a machine's OPC UA server.

    Parameters
    ----------
    endpoint
        ``opc.tcp://HOST:PORT[/path]``.
    axis
        The axis object's browse name (``X`` for a single-axis scenario).
    security
        How to connect (none, or Basic256Sha256 with a certificate, key, user).
    poll_s
        Longest wait between two reads of ``Sequence`` without a notification, s.
    reconnect_timeout_s
        Longest time without a connection before :class:`LinkLost`, s.
    """

    def __init__(
        self,
        endpoint: str,
        axis: str,
        security: Security | None = None,
        poll_s: float = 1.0,
        reconnect_timeout_s: float = 60.0,
    ) -> None:
        if not endpoint.startswith("opc.tcp://"):
            raise LinkRefused(f"--endpoint {endpoint!r}: expected opc.tcp://HOST:PORT")
        self.endpoint = endpoint
        self.axis = axis
        self.security = security or Security()
        self.poll_s = poll_s
        self.reconnect_timeout_s = reconnect_timeout_s
        self.last: int | None = None  # the Sequence of the last window read
        self.missed = 0
        self.reads = 0
        self.notifications = 0
        self._client: Any = None
        self._twin: dict[str, Any] = {}
        self._wake = asyncio.Event()
        logging.getLogger("asyncua").setLevel(logging.CRITICAL)

    async def _connect(self) -> tuple[Any, Any, dict[str, Any]]:
        """A connected client, the Sequence node and the array nodes by name."""
        from asyncua import Client, ua
        from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

        client = Client(self.endpoint, timeout=REQUEST_TIMEOUT_S)
        security = self.security
        if security.secured:
            client.application_uri = application_uri(security.certificate) or CLIENT_URI
            await client.set_security(
                SecurityPolicyBasic256Sha256,
                str(security.certificate),
                str(security.private_key),
                mode=getattr(ua.MessageSecurityMode, security.mode),
            )
        if security.user:
            client.set_user(security.user)
            client.set_password(security.password or "")
        await client.connect()
        try:
            sequence, arrays = await self._browse(client)
        except BaseException:
            await _close(client)
            raise
        return client, sequence, arrays

    async def _browse(self, client: Any) -> tuple[Any, dict[str, Any]]:
        """The trace's nodes, found by the namespace URI and the browse names."""
        from asyncua import ua

        try:
            ns = await client.get_namespace_index(MACHINE_NAMESPACE)
        except ValueError:
            raise LinkRefused(
                f"{self.endpoint}: the server has no namespace {MACHINE_NAMESPACE} "
                "(docs/runtime.md: the information model)"
            ) from None
        path = [f"{ns}:{MACHINE}", f"{ns}:{self.axis}", f"{ns}:{TRACE}"]
        try:
            trace = await client.nodes.objects.get_child(path)
        except ua.UaStatusCodeError:
            axes = await self._axes(client, ns)
            raise LinkRefused(
                f"{self.endpoint}: no Objects/{MACHINE}/{self.axis}/{TRACE} in namespace "
                f"{MACHINE_NAMESPACE} (axes found: {', '.join(axes) or 'none'})"
            ) from None
        nodes: dict[str, Any] = {}
        for name in (*REQUIRED_ARRAYS, *OPTIONAL_ARRAYS, SEQUENCE):
            try:
                nodes[name] = await trace.get_child(f"{ns}:{name}")
            except ua.UaStatusCodeError:
                if name not in OPTIONAL_ARRAYS:
                    raise LinkRefused(
                        f"{self.endpoint}: {MACHINE}/{self.axis}/{TRACE} has no variable {name!r}"
                    ) from None
        await self._find_twin(client)
        return nodes.pop(SEQUENCE), nodes

    async def _axes(self, client: Any, ns: int) -> list[str]:
        from asyncua import ua

        try:
            machine = await client.nodes.objects.get_child(f"{ns}:{MACHINE}")
            return [(await c.read_browse_name()).Name for c in await machine.get_children()]
        except ua.UaStatusCodeError:
            return []

    async def _find_twin(self, client: Any) -> None:
        """The twin's namespace nodes, when the server offers them."""
        from asyncua import ua

        self._twin = {}
        try:
            ns = await client.get_namespace_index(TWIN_NAMESPACE)
            twin = await client.nodes.objects.get_child(f"{ns}:{TWIN}")
            for name in TWIN_VARIABLES:
                self._twin[name] = await twin.get_child(f"{ns}:{name}")
        except (ValueError, ua.UaStatusCodeError):
            self._twin = {}

    @property
    def twin_writable(self) -> bool:
        """Whether the server offers the twin's namespace (writes may still be refused)."""
        return bool(self._twin)

    async def write_twin(self, values: dict[str, Any]) -> bool:
        """Write values into the twin's namespace (name -> value); False when the server does
        not offer it or refuses the write (then it is not tried again)."""
        from asyncua import ua

        if not self._twin or self._client is None:
            return False
        try:
            for name, value in values.items():
                kind = getattr(ua.VariantType, TWIN_VARIABLES[name])
                await self._twin[name].write_value(ua.DataValue(ua.Variant(value, kind)))
        except ua.UaStatusCodeError:
            self._twin = {}
            return False
        except (ConnectionError, OSError, asyncio.TimeoutError):
            return False
        return True

    async def events(self) -> AsyncIterator[LinkEvent]:
        """The windows as they come, and what happens to the link, until cancelled.

        Raises
        ------
        LinkRefused
            The server refuses the client or lacks the model.
        LinkLost
            No connection for longer than the reconnection timeout.
        """
        from asyncua import ua

        connected_once = False
        lost_since = time.monotonic()
        backoff = FIRST_BACKOFF_S
        while True:
            try:
                client, sequence, arrays = await asyncio.wait_for(
                    self._connect(), REQUEST_TIMEOUT_S
                )
            except LinkRefused:
                raise
            except (OSError, asyncio.TimeoutError, ua.UaError, ConnectionError) as exc:
                refusal = _refusal(exc)
                if refusal:
                    raise LinkRefused(self._refused_text(refusal)) from None
                waited = time.monotonic() - lost_since
                if waited > self.reconnect_timeout_s:
                    what = "reconnect to" if connected_once else "reach"
                    raise LinkLost(
                        f"could not {what} {self.endpoint} for {waited:.0f} s "
                        f"({type(exc).__name__}: {exc or 'no answer'})"
                    ) from None
                await asyncio.sleep(backoff)
                backoff = min(2 * backoff, MAX_BACKOFF_S)
                continue
            self._client = client
            backoff = FIRST_BACKOFF_S
            kind = "restored" if connected_once else "connected"
            yield Notice(kind, f"connected to {self.endpoint} ({self.security.mode})")
            if not self._twin:
                yield Notice("twin_namespace", f"{self.endpoint} offers no {TWIN_NAMESPACE}")
            connected_once = True
            try:
                async for event in self._follow(client, sequence, arrays):
                    yield event
            except (OSError, asyncio.TimeoutError, ua.UaError, ConnectionError) as exc:
                yield Notice("lost", f"connection to {self.endpoint} lost ({type(exc).__name__})")
            finally:
                self._client = None
                await _close(client)
            lost_since = time.monotonic()

    def _refused_text(self, code: str) -> str:
        hint = (
            "it asks for a security policy: give --security Sign|SignAndEncrypt, "
            "--certificate and --private-key"
            if "Security" in code or "Certificate" in code
            else "it asks for a user: set TWIN_OPCUA_USER and TWIN_OPCUA_PASSWORD"
        )
        return f"{self.endpoint} refused the connection ({code}): {hint}"

    async def _follow(self, client: Any, sequence: Any, arrays: dict[str, Any]):
        """Follow ``Sequence`` on one connection; yields the windows and the missed ones."""
        wake = _Wake(self._wake)
        subscription = await client.create_subscription(
            max(50.0, min(500.0, self.poll_s * 250.0)), wake
        )
        await subscription.subscribe_data_change(sequence, queuesize=1)
        nodes = list(arrays.values())
        while True:
            try:
                await asyncio.wait_for(self._wake.wait(), self.poll_s)
            except asyncio.TimeoutError:
                pass  # the poll: notifications may have stopped
            self._wake.clear()
            self.notifications = wake.notifications
            now = int(await sequence.read_value())
            if now == self.last:
                continue
            if now == 0:  # nothing published yet, or since the server restarted
                for event in self._sequence_events(0):
                    yield event
                self.last = 0
                continue
            values = await client.read_values([sequence, *nodes])
            self.reads += 1
            read = int(values[0])
            for event in self._sequence_events(read):
                yield event
            self.last = read
            received = {
                name: list(v) if v is not None else None
                for name, v in zip(arrays, values[1:], strict=True)
            }
            yield Received(read, received, time.time())

    def _sequence_events(self, read: int) -> list[LinkEvent]:
        """What a Sequence read after :attr:`last` says: windows missed, a restart."""
        if self.last is None:
            return []
        if read < self.last and self.last - read < SEQUENCE_MODULUS // 2:
            events: list[LinkEvent] = [
                Notice(
                    "restarted",
                    f"Sequence fell from {self.last} to {read}: the server "
                    "restarted; counting from there",
                )
            ]
            if read > 1:  # windows published since the restart before this one
                self.missed += read - 1
                events.append(Missed(read - 1, 0, read))
            return events
        gap = (read - self.last - 1) % SEQUENCE_MODULUS
        if gap:
            self.missed += gap
            return [Missed(gap, self.last, read)]
        return []


async def _close(client: Any) -> None:
    """Disconnect, ignoring a connection already gone."""
    try:
        await asyncio.wait_for(client.disconnect(), 2.0)
    except Exception:  # noqa: BLE001 - the connection is being dropped anyway
        pass
