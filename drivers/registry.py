"""Driver registry: name -> "module:Class", extended through an entry-point group.

Built-in drivers are listed here as strings; third-party packages add theirs
to the ``stiffness_campaign.drivers`` entry-point group. A driver's module is
imported only when that driver is chosen, so a missing optional dependency
only matters for the driver that needs it.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from typing import Any

from drivers.errors import DriverError, DriverNotFound

ENTRY_POINT_GROUP = "stiffness_campaign.drivers"

BUILTIN: dict[str, str] = {
    # force/torque
    "ati-netft": "drivers.ati_netft:NetFTSensor",
    "robotiq-ft300": "drivers.robotiq_ft300:FT300Sensor",
    "ati-netcan": "drivers.ati_netcan:NetCANSensor",
    # pose measurement
    "emscon": "drivers.emscon:EmsconTracker",
    "geocom": "drivers.geocom:GeoComTracker",
    # robots
    "ur": "drivers.ur:URRobot",
    "kuka-kvp": "drivers.kuka_kvp:KukaVarProxyRobot",
    "fanuc-rmi": "drivers.fanuc_rmi:FanucRMIRobot",
    "abb-rws": "drivers.abb_rws:ABBRWSRobot",
    "abb-rws2": "drivers.abb_rws:ABBRWSRobot",  # the same; names the RobotWare 7 fake
    "manual": "drivers.manual:ManualRobot",
    # loads
    "manual-load": "drivers.manual:ManualLoad",
    "lab-load": "drivers.sim.lab_load:LabLoadApplicator",
}


def available_drivers() -> dict[str, str]:
    """All known driver names mapped to ``"module:Class"`` (entry points override built-ins)."""
    table = dict(BUILTIN)
    try:
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            table[ep.name] = ep.value
    except Exception:  # a broken installation must not hide the built-ins
        pass
    return table


def load_driver_class(name: str) -> type:
    """Import and return the class registered as ``name``.

    Raises
    ------
    DriverNotFound
        If no driver has that name, or its module or class cannot be imported
        (the message names the missing module).
    """
    table = available_drivers()
    if name not in table:
        raise DriverNotFound(f"no driver named {name!r}; known: {', '.join(sorted(table))}")
    target = table[name]
    module_name, _, attr = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as err:
        raise DriverNotFound(
            f"driver {name!r} needs module {module_name!r}, which cannot be imported: {err}"
        ) from err
    try:
        return getattr(module, attr)
    except AttributeError as err:
        raise DriverNotFound(f"driver {name!r}: {module_name} has no {attr!r}") from err


def open_driver(name: str, address: str, **options: Any) -> Any:
    """Build (not connect) the driver ``name`` for ``address``.

    Example: ``open_driver("ati-netft", "udp://192.168.1.1:49152")``.
    """
    cls = load_driver_class(name)
    try:
        return cls(address, **options)
    except DriverError:
        raise
    except TypeError as err:
        raise DriverError(f"driver {name!r}: bad options {sorted(options)}: {err}") from err
