"""Address parsing, the driver registry and the exception tree."""

from __future__ import annotations

import sys

import pytest

from drivers import errors, registry
from drivers.address import parse_address
from drivers.errors import AddressError, DriverNotFound


@pytest.mark.parametrize(
    ("text", "scheme", "host", "port", "path", "options"),
    [
        ("udp://192.168.1.1:49152", "udp", "192.168.1.1", 49152, "", {}),
        ("socket://10.0.0.5:7000", "tcp", "10.0.0.5", 7000, "", {}),
        ("/dev/ttyUSB0?baud=19200", "serial", "", None, "/dev/ttyUSB0", {"baud": "19200"}),
        ("serial:///dev/ttyS1", "serial", "", None, "/dev/ttyS1", {}),
        ("can://can0?interface=socketcan&base_id=0x7f", "can", "", None, "can0",
         {"interface": "socketcan", "base_id": "0x7f"}),
        ("ur://192.168.0.20", "ur", "192.168.0.20", None, "", {}),
        ("manual://", "manual", "", None, "", {}),
    ],
)
def test_parse_address(text, scheme, host, port, path, options):
    a = parse_address(text)
    assert (a.scheme, a.host, a.port, a.path, a.options) == (scheme, host, port, path, options)


def test_address_options_are_typed():
    a = parse_address("can://can0?base_id=0x7f&bitrate=500000&gain=1.5")
    assert a.int_option("base_id", 0) == 0x7F
    assert a.int_option("bitrate", 0) == 500000
    assert a.float_option("gain", 0.0) == 1.5
    assert a.int_option("missing", 3) == 3
    with pytest.raises(AddressError, match="not an integer"):
        parse_address("can://can0?base_id=zz").int_option("base_id", 0)


@pytest.mark.parametrize("text", ["", "   ", "192.168.1.1", "ftp://x:1", "udp://:5",
                                  "udp://host:99999", "can://", "serial://"])
def test_bad_addresses_raise_address_error(text):
    with pytest.raises(AddressError):
        parse_address(text)


def test_exception_leaves_inherit_builtins():
    assert issubclass(errors.ConnectionFailed, ConnectionError)
    assert issubclass(errors.DeviceTimeout, TimeoutError)
    assert issubclass(errors.ProtocolError, ValueError)
    for leaf in (errors.ConnectionFailed, errors.DeviceTimeout, errors.ProtocolError,
                 errors.DeviceFault, errors.SafetyRefusal, errors.DriverNotFound,
                 errors.AddressError):
        assert issubclass(leaf, errors.DriverError)


def test_registry_lists_builtins_and_loads_a_class():
    names = registry.available_drivers()
    for name in ("ati-netft", "robotiq-ft300", "ati-netcan", "emscon", "geocom", "ur",
                 "kuka-kvp", "fanuc-rmi", "abb-rws", "abb-rws2", "manual", "manual-load",
                 "lab-load"):
        assert name in names
    cls = registry.load_driver_class("ati-netft")
    assert cls.__name__ == "NetFTSensor"


def test_registry_unknown_name_lists_known_ones():
    with pytest.raises(DriverNotFound, match="no driver named 'nope'.*ati-netft"):
        registry.load_driver_class("nope")


def test_registry_missing_module_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(registry.BUILTIN, "ghost", "drivers.does_not_exist:Ghost")
    with pytest.raises(DriverNotFound, match="drivers.does_not_exist"):
        registry.load_driver_class("ghost")


def test_registry_entry_points_extend_and_import_lazily(monkeypatch):
    class EP:
        name, value = "third-party", "fractions:Fraction"

    monkeypatch.setattr(registry, "entry_points", lambda group: [EP] if group ==
                        registry.ENTRY_POINT_GROUP else [])
    monkeypatch.delitem(sys.modules, "fractions", raising=False)
    assert registry.available_drivers()["third-party"] == "fractions:Fraction"
    assert "fractions" not in sys.modules  # listing does not import
    assert registry.load_driver_class("third-party").__name__ == "Fraction"


def test_open_driver_builds_without_connecting():
    drv = registry.open_driver("ati-netft", "udp://127.0.0.1:9")
    assert drv.connected is False and drv.port == 9 and drv.http_port == 80
    with pytest.raises(errors.ConnectionFailed, match="udp"):
        registry.open_driver("ati-netft", "socket://127.0.0.1:9")
