"""Loopback-only mode: every driver refuses to connect to a device off this machine.

The test suite, the demo and the simulated lab set the environment variable
``STIFFNESS_CAMPAIGN_LOOPBACK_ONLY=1`` (inherited by every process they start), so that
no test input, fuzzed request or copied protocol can send traffic to a real instrument
or robot: the address's host must then be a loopback literal (127.0.0.0/8, ``::1``) or
``localhost``. A host name is not resolved (the lookup itself would leave the machine).
Serial ports and local CAN channels are not network traffic and are not checked; a
CAN address routed through a socketcand server (``host=`` option) is.
"""

from __future__ import annotations

import ipaddress
import os
from collections.abc import Iterator
from contextlib import contextmanager

from drivers.address import parse_address
from drivers.errors import AddressError, ConnectionFailed

ENV = "STIFFNESS_CAMPAIGN_LOOPBACK_ONLY"


def loopback_only() -> bool:
    """True when the environment asks for loopback-only connections."""
    return os.environ.get(ENV, "").strip() not in ("", "0")


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
        raise ConnectionFailed(f"{text}: {host} is not a loopback address, and {ENV} is set "
                               "(tests, demos and the simulated lab connect to this machine "
                               "only)")


@contextmanager
def loopback_only_mode(on: bool = True) -> Iterator[None]:
    """Within the block (when ``on``), loopback-only mode is set for this process and the
    processes it starts; the former value is restored after."""
    if not on:
        yield
        return
    before = os.environ.get(ENV)
    os.environ[ENV] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = before
