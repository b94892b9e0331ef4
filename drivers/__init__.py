"""Instrument drivers (robots, force/torque sensors, trackers, loads) and simulated fakes.

Public API for a campaign runner:

- :func:`drivers.registry.open_driver` ``(name, address, **options)`` builds a
  driver from its registry name (``ati-netft``, ``robotiq-ft300``, ``ati-netcan``,
  ``emscon``, ``geocom``, ``ur``, ``kuka-kvp``, ``fanuc-rmi``, ``abb-rws``, ``abb-rws2``,
  ``manual``, ``manual-load``,
  ``lab-load``, or any name added through the ``stiffness_campaign.drivers``
  entry-point group) and an address string (:func:`drivers.address.parse_address`).
- Roles in :mod:`drivers.roles`: ``RobotController``, ``ForceTorqueSensor``,
  ``PoseTracker``, ``LoadApplicator`` (with ``LoadCase``); readings in
  :mod:`drivers.readings`; errors in :mod:`drivers.errors`.
- :mod:`drivers.frames` (wrench to base frame, rigid fit) and :mod:`drivers.safety`.
- The simulated lab: :class:`drivers.sim.lab.Lab` with
  :class:`drivers.sim.settings.LabSettings`; control channel client
  :class:`drivers.sim.control.LabClient`.

Everything is SI inside: m, rad, N, N m.
"""

from drivers.address import Address, parse_address
from drivers.errors import (
    AddressError,
    ConnectionFailed,
    DeviceFault,
    DeviceTimeout,
    DriverError,
    DriverNotFound,
    ProtocolError,
    SafetyRefusal,
)
from drivers.registry import available_drivers, load_driver_class, open_driver

__all__ = [
    "Address",
    "AddressError",
    "ConnectionFailed",
    "DeviceFault",
    "DeviceTimeout",
    "DriverError",
    "DriverNotFound",
    "ProtocolError",
    "SafetyRefusal",
    "available_drivers",
    "load_driver_class",
    "open_driver",
    "parse_address",
]
