"""The OPC UA link between a machine and the twin: the information model and the window it
carries, the link's security, the twin's client and the virtual machine's server.

**The information model** of a machine that publishes trace windows, and the window it carries:
the one place of its names, shared by the virtual machine's server and the twin's client.

The model (docs/runtime.md), every browse name in the namespace :data:`MACHINE_NAMESPACE`::

    Objects
      Machine                      object (a machine tool, as OPC UA for Machine Tools names it)
        <axis>                     object, named as the scenario's axis (X for a single axis)
          Trace                    object: one window of the drive's trace
            time                   Double[]  s
            position_reference     Double[]  m
            position               Double[]  m
            current                Double[]  A
            motor_speed            Double[]  rad/s (optional)
            Sequence               UInt32: incremented after a window's arrays are all written

The arrays of a window are sampled at the position-loop period. A client finds the namespace
index from its URI, browses by these names, subscribes to ``Sequence`` and reads the arrays when
it changes.

The twin writes what it finds into a namespace of its own, :data:`TWIN_NAMESPACE`, when the
server offers it and allows writing::

    Objects
      Twin                         object
        Window                     UInt32: the last window the twin checked (its Sequence)
        Gap                        Double: that window's normalised RMS gap (1: the noise floor)
        Alarms                     UInt32: alarms raised so far
        Alarm                      String: the last alarm, as its JSON line of the log

**Security** of the OPC UA link as a CNC's server demands it: the Basic256Sha256 policy with Sign
or SignAndEncrypt, an application certificate and key, and a user name and password.

The password is read from the environment only (:data:`USER_ENV`, :data:`PASSWORD_ENV`), never
from the command line or a log. :func:`self_signed` makes a certificate and key (tests make them
at run time in a temporary folder; no key is ever committed).

**The client**, the twin's OPC UA link to the machine: connect (with the security a CNC asks
for), find the model by its namespace URI and browse names, follow ``Sequence``, read each window
once, count the windows missed, and survive the server going away.

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

**The server** of the information model on 127.0.0.1, and the virtual machine behind it
(``twin serve``).

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
import math
import multiprocessing
import os
import socket
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

MACHINE_NAMESPACE = "urn:twin-cosim:machine"
TWIN_NAMESPACE = "urn:twin-cosim:twin"
MACHINE = "Machine"
TRACE = "Trace"
SEQUENCE = "Sequence"
SINGLE_AXIS = "X"  # the axis of a single-axis scenario
# The arrays of a window: browse name -> unit; motor_speed may be missing.
ARRAYS = {
    "time": "s",
    "position_reference": "m",
    "position": "m",
    "current": "A",
    "motor_speed": "rad/s",
}
REQUIRED_ARRAYS = ("time", "position_reference", "position", "current")
OPTIONAL_ARRAYS = ("motor_speed",)
TWIN = "Twin"
TWIN_VARIABLES = {"Window": "UInt32", "Gap": "Double", "Alarms": "UInt32", "Alarm": "String"}
SEQUENCE_MODULUS = 2**32  # Sequence is a UInt32: it wraps to 0 after 2^32 - 1
PERIOD_TOLERANCE = 1e-6  # relative: a window's sample period against the position loop's


class WindowError(ValueError):
    """A window that cannot be checked (its message names the window and what is wrong)."""


@dataclass(frozen=True)
class Window:
    """One trace window of an axis as the machine published it.

    Attributes
    ----------
    sequence : int
        The server's ``Sequence`` after the window was written.
    time : numpy.ndarray
        Sample times, s (any origin; the window's own clock).
    position_reference : numpy.ndarray
        The position reference of the window, m.
    position : numpy.ndarray
        The measured carriage position, m.
    current : numpy.ndarray
        The current command, A.
    motor_speed : numpy.ndarray or None
        The measured motor speed, rad/s, when the server publishes it.
    """

    sequence: int
    time: np.ndarray
    position_reference: np.ndarray
    position: np.ndarray
    current: np.ndarray
    motor_speed: np.ndarray | None = None

    @property
    def samples(self) -> int:
        """Number of samples."""
        return len(self.time)

    @property
    def period(self) -> float:
        """Sample period, s."""
        return float((self.time[-1] - self.time[0]) / (len(self.time) - 1))

    @property
    def duration(self) -> float:
        """Time the window covers, s (samples times the period)."""
        return self.samples * self.period

    def arrays(self) -> dict[str, np.ndarray]:
        """The window's arrays by browse name (``motor_speed`` only when present)."""
        named = {name: getattr(self, name) for name in REQUIRED_ARRAYS}
        if self.motor_speed is not None:
            named["motor_speed"] = self.motor_speed
        return named


def window_of(sequence: int, arrays: dict[str, object], label: str) -> Window:
    """A checked window from the arrays read off the server.

    Parameters
    ----------
    sequence
        The window's ``Sequence``.
    arrays
        Browse name -> values read (lists of numbers); ``motor_speed`` may be missing or empty.
    label
        How messages name the window (e.g. ``window 12 (Sequence 13)``).

    Raises
    ------
    WindowError
        A required array missing or not numeric, arrays of unequal length, fewer than 8
        samples, a value that is NaN or infinite, or time not increasing at a regular step.
    """
    values: dict[str, np.ndarray] = {}
    for name in ARRAYS:
        raw = arrays.get(name)
        if raw is None or (name in OPTIONAL_ARRAYS and len(raw) == 0):  # type: ignore[arg-type]
            if name in REQUIRED_ARRAYS:
                raise WindowError(f"{label}: no array {name!r}")
            continue
        try:
            values[name] = np.asarray(raw, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise WindowError(f"{label}: array {name!r} is not a Double array") from None
    lengths = {name: len(v) for name, v in values.items()}
    if len(set(lengths.values())) != 1:
        raise WindowError(f"{label}: arrays of unequal length {lengths}")
    if lengths["time"] < 8:
        raise WindowError(f"{label}: {lengths['time']} samples; a window needs at least 8")
    for name, v in values.items():
        bad = np.flatnonzero(~np.isfinite(v))
        if len(bad):
            raise WindowError(
                f"{label}: {name} holds {len(bad)} NaN or infinite values (first at sample "
                f"{bad[0]})"
            )
    steps = np.diff(values["time"])
    step = float(np.median(steps))
    if step <= 0 or np.max(np.abs(steps - step)) > 1e-3 * step:
        raise WindowError(f"{label}: time must increase at a regular step")
    return Window(
        sequence,
        values["time"],
        values["position_reference"],
        values["position"],
        values["current"],
        values.get("motor_speed"),
    )


def check_period(window: Window, loop_period: float, label: str) -> None:
    """Refuse a window not sampled at the scenario's position-loop period (s)."""
    if not math.isclose(window.period, loop_period, rel_tol=PERIOD_TOLERANCE):
        raise WindowError(
            f"{label}: sampled every {window.period * 1e6:.6g} us; the scenario's position loop "
            f"runs every {loop_period * 1e6:.6g} us (windows must be sampled at the "
            "position-loop period)"
        )


def sequence_gap(previous: int, current: int) -> int:
    """Windows missed between two Sequence values read one after the other (UInt32, wrapping);
    0 when ``current`` follows ``previous``."""
    return (current - previous - 1) % SEQUENCE_MODULUS


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
        except (TimeoutError, ConnectionError, OSError):
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
            except (TimeoutError, OSError, ua.UaError, ConnectionError) as exc:
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
            except (TimeoutError, OSError, ua.UaError, ConnectionError) as exc:
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
            except TimeoutError:
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
