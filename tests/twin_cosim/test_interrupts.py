"""Ctrl-C and SIGTERM are raised where they are safe: after a deferred block, never lost."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from twin_cosim.interrupts import deferred_signals, stop_handlers, wait_interruptibly


def test_a_signal_in_a_deferred_block_is_raised_at_its_end():
    reached_the_end = False
    with pytest.raises(KeyboardInterrupt):
        with deferred_signals() as deferral:
            signal.raise_signal(signal.SIGINT)
            assert deferral.signum == signal.SIGINT
            reached_the_end = True
    assert reached_the_end


def test_a_signal_ignored_outside_stays_ignored():
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred_signals():
            signal.raise_signal(signal.SIGINT)
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_wait_ends_on_a_signal_from_another_thread():
    """The wait never answers: only the signal ends it, as a KeyboardInterrupt."""
    sender = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    sender.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            wait_interruptibly(lambda timeout_s: threading.Event().wait(timeout_s) or None)
    finally:
        sender.join()


def test_a_second_signal_is_absorbed_while_the_first_is_handled():
    """``timeout -s INT`` signals a command, then its group: the shutdown the first signal began
    (its ``finally`` and ``except`` blocks) runs to its end."""
    shut_down = False
    with stop_handlers():
        try:
            signal.raise_signal(signal.SIGINT)
            pytest.fail("not raised")
        except KeyboardInterrupt:
            signal.raise_signal(signal.SIGINT)  # during the shutdown: absorbed
            signal.raise_signal(signal.SIGTERM)
            shut_down = True
    assert shut_down
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


class Dropped:
    """An object whose finalizer receives the Ctrl-C (Python drops what it raises there)."""

    def __del__(self) -> None:
        signal.raise_signal(signal.SIGINT)


@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning")
def test_a_ctrl_c_python_dropped_stops_the_next_wait():
    """Seen on a Dask campaign: the Ctrl-C landed in a weakref callback, Python printed
    "Exception ignored in ... Traceback" and the campaign ran to its end. Now it says nothing
    (no unraisable exception reaches the hook before) and the next wait raises the stop."""
    with stop_handlers():
        Dropped()  # its finalizer runs here, and the KeyboardInterrupt it raises is dropped
        with pytest.raises(KeyboardInterrupt):
            wait_interruptibly(lambda timeout_s: "answered")
