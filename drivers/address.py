"""Device addresses as URL-like strings, parsed by one function.

Accepted forms (examples)::

    udp://192.168.1.1:49152          ATI Net F/T (RDT)
    socket://192.168.1.10:7000       TCP (KUKAVARPROXY, emScon tracker)
    tcp://127.0.0.1:5000             same as socket://
    http://192.168.1.1               calibration page
    /dev/ttyUSB0?baud=19200          serial port, options as query string
    serial:///dev/ttyUSB0?baud=19200 same, explicit
    can://can0?interface=socketcan&base_id=0x7f
    ur://192.168.1.20                Universal Robots controller (RTDE)
    lab://127.0.0.1:40000            control channel of the simulated lab
    manual://                        operator at the teach pendant
    rmi://192.168.1.30               FANUC RMI (handshake port 16001)
    rws://Default%20User:robotics@192.168.125.1       ABB RWS 1.0 (RobotWare 6, HTTP)
    rws2://Admin:robotics@192.168.125.1?insecure=1    ABB RWS 2.0 (RobotWare 7, HTTPS)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, urlsplit

from drivers.errors import AddressError

_NETWORK = {"udp", "tcp", "socket", "http", "ur", "lab", "kvp", "rmi", "rws", "rws2"}


@dataclass(frozen=True)
class Address:
    """A parsed device address.

    Attributes
    ----------
    scheme : str
        ``udp``, ``tcp`` (``socket`` is normalised to ``tcp``), ``serial``,
        ``can``, ``http``, ``ur``, ``lab``, ``manual``...
    host : str
        Host name or IP (network schemes), else empty.
    port : int or None
        Port number if given.
    path : str
        Serial device path, or CAN channel name.
    options : dict of str to str
        Query-string options (``baud``, ``interface``, ``base_id``...).
    """

    scheme: str
    host: str = ""
    port: int | None = None
    path: str = ""
    options: dict[str, str] = field(default_factory=dict)
    text: str = ""
    user: str = ""
    password: str = ""

    def option(self, name: str, default: str | None = None) -> str | None:
        """Return the query option ``name``, or ``default``."""
        return self.options.get(name, default)

    def int_option(self, name: str, default: int) -> int:
        """Return an integer option (decimal or ``0x`` hexadecimal)."""
        raw = self.options.get(name)
        if raw is None:
            return default
        try:
            return int(raw, 0)
        except ValueError as err:
            raise AddressError(f"{self.text!r}: option {name}={raw!r} is not an integer") from err

    def float_option(self, name: str, default: float) -> float:
        """Return a float option."""
        raw = self.options.get(name)
        if raw is None:
            return default
        try:
            return float(raw)
        except ValueError as err:
            raise AddressError(f"{self.text!r}: option {name}={raw!r} is not a number") from err

    def with_default_port(self, port: int) -> Address:
        """Return a copy whose port is ``port`` when none was given."""
        if self.port is not None:
            return self
        return Address(self.scheme, self.host, port, self.path, dict(self.options), self.text,
                       self.user, self.password)


def parse_address(text: str) -> Address:
    """Parse a device address string.

    Parameters
    ----------
    text : str
        Address such as ``udp://host:port``, ``/dev/ttyUSB0?baud=19200`` or
        ``can://can0?interface=socketcan``.

    Returns
    -------
    Address

    Raises
    ------
    AddressError
        If the text is empty, has an unknown scheme, or a bad port.
    """
    if not isinstance(text, str) or not text.strip():
        raise AddressError("empty device address")
    text = text.strip()
    if text.startswith("/") or text.upper().startswith("COM"):
        text_for_split = "serial://" + text
    else:
        text_for_split = text
    if "://" not in text_for_split:
        raise AddressError(
            f"{text!r}: expected scheme://..., e.g. udp://192.168.1.1:49152, "
            "socket://host:7000, /dev/ttyUSB0?baud=19200 or can://can0?interface=socketcan"
        )
    parts = urlsplit(text_for_split)
    scheme = parts.scheme.lower()
    if scheme == "socket":
        scheme = "tcp"
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    if scheme == "serial":
        path = (parts.netloc + parts.path) if parts.netloc else parts.path
        if not path:
            raise AddressError(f"{text!r}: serial address without a device path")
        return Address("serial", path=path, options=options, text=text)
    if scheme == "can":
        channel = parts.netloc or parts.path.lstrip("/")
        if not channel:
            raise AddressError(f"{text!r}: CAN address without a channel")
        return Address("can", path=channel, options=options, text=text)
    if scheme == "manual":
        return Address("manual", options=options, text=text)
    if scheme not in _NETWORK:
        raise AddressError(
            f"{text!r}: unknown scheme {parts.scheme!r} "
            f"(known: {', '.join(sorted(_NETWORK | {'serial', 'can', 'manual', 'socket'}))})"
        )
    try:
        port = parts.port
    except ValueError as err:
        raise AddressError(f"{text!r}: bad port") from err
    host = parts.hostname or ""
    if not host:
        raise AddressError(f"{text!r}: missing host")
    from urllib.parse import unquote

    return Address(scheme, host=host, port=port, path=parts.path, options=options, text=text,
                   user=unquote(parts.username or ""), password=unquote(parts.password or ""))
