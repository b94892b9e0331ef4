"""Exception tree of the instrument drivers.

Every error a driver raises derives from :class:`DriverError`. The leaves also
derive from the built-in exception they mean, so callers that only know the
standard library (``except TimeoutError``) still catch them. Errors from
libraries (``socket``, ``serial``, ``can``, ``ur-rtde``) are wrapped at the
driver boundary with ``raise ... from err`` so the original cause is kept.
"""

from __future__ import annotations


class DriverError(Exception):
    """Base of every error raised by an instrument driver."""


class ConnectionFailed(DriverError, ConnectionError):
    """The device could not be reached, or the link dropped."""


class DeviceTimeout(DriverError, TimeoutError):
    """The device did not answer within the allowed time."""


class ProtocolError(DriverError, ValueError):
    """Bytes from the device do not follow the protocol (framing, CRC, length, content)."""


class DeviceFault(DriverError):
    """The device answered correctly but reports a fault (status bits, error codes, lost beam)."""


class SafetyRefusal(DriverError):
    """An action was refused because it would break a safety limit."""


class DriverNotFound(DriverError, LookupError):
    """No driver is registered under the requested name, or its module cannot be imported."""


class AddressError(DriverError, ValueError):
    """A device address string cannot be parsed."""
