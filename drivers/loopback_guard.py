"""Loopback-only mode: every driver refuses to connect to a device off this machine.

The mode has two scopes, so that concurrent jobs of one process (the GUI server's request
and job threads) cannot change each other's:

- In this process, per job: :func:`loopback_only_mode` sets it for the code running in
  its block, in the block's own :mod:`contextvars` context (the thread, or the asyncio
  task, that entered it). A simulated-lab run, the demo and a dry run on the fakes use
  it; a hardware run in another thread of the same server is not affected, and the end
  of one fake run does not lift the mode of another still running.
- For a whole process and the processes it starts: the environment variable
  ``STIFFNESS_CAMPAIGN_LOOPBACK_ONLY=1``. The test suite sets it for its session
  (``tests/conftest.py``); a child process started from a job in loopback-only mode gets
  it through :func:`child_environment`.

The mode of the current code is on when either says so (:func:`loopback_only`): a job's
block can add the mode, never lift the process's, so that no test, fuzzed request or
copied protocol sends traffic to a real instrument or robot. In the mode the address's
host must be a loopback literal (127.0.0.0/8, ``::1``) or ``localhost``. A host name is
not resolved (the lookup itself would leave the machine). Serial ports and local CAN
channels are not network traffic and are not checked; a CAN address routed through a
socketcand server (``host=`` option) is.

The check runs in :meth:`drivers.roles.Driver.connect`, in the thread that connects. A
thread started inside a block does not inherit the block's context (Python starts a
thread in an empty one): code that connects from a thread of its own runs it in
:func:`contextvars.copy_context` of its starter.
"""

from __future__ import annotations

import ipaddress
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar

from drivers.address import parse_address
from drivers.errors import AddressError, ConnectionFailed

ENV = "STIFFNESS_CAMPAIGN_LOOPBACK_ONLY"

#: loopback-only mode set by :func:`loopback_only_mode` in the current context
_IN_CONTEXT: ContextVar[bool] = ContextVar("loopback_only", default=False)


def _environment_says(environ: Mapping[str, str]) -> bool:
    return environ.get(ENV, "").strip() not in ("", "0")


def loopback_only() -> bool:
    """True when the current context (:func:`loopback_only_mode`) or the process's
    environment (``STIFFNESS_CAMPAIGN_LOOPBACK_ONLY``) asks for loopback-only
    connections."""
    return _IN_CONTEXT.get() or _environment_says(os.environ)


def is_loopback_host(host: str) -> bool:
    """True for a loopback IP literal (127.0.0.0/8, ``::1``, bracketed or not) or
    ``localhost`` (no name is resolved)."""
    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_address(text: str) -> None:
    """Raise ConnectionFailed if loopback-only mode is on and ``text`` names a network
    device off this machine (an unparsable address is left to the driver's own check)."""
    if not loopback_only() or not text:
        return
    try:
        address = parse_address(text)
    except AddressError:
        return
    host = address.host or address.options.get("host", "")
    if host and not is_loopback_host(host):
        raise ConnectionFailed(f"{text}: {host} is not a loopback address, and loopback-only "
                               f"mode is on ({ENV}: tests, demos and the simulated lab "
                               "connect to this machine only)")


@contextmanager
def loopback_only_mode(on: bool = True) -> Iterator[None]:
    """Within the block (when ``on``), loopback-only mode is on for the code of the
    current context (this thread or asyncio task; not for other jobs of this process),
    and for the processes it starts with :func:`child_environment`. The former setting
    is restored after. ``on`` False adds nothing: the process's own setting stands."""
    if not on:
        yield
        return
    token = _IN_CONTEXT.set(True)
    try:
        yield
    finally:
        _IN_CONTEXT.reset(token)


def child_environment(environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment for a process started now (a copy of ``environ``, default
    ``os.environ``), with ``STIFFNESS_CAMPAIGN_LOOPBACK_ONLY=1`` when the current code
    is in loopback-only mode: the child's drivers are held to loopback as the starter's."""
    env = dict(os.environ if environ is None else environ)
    if loopback_only():
        env[ENV] = "1"
    return env
