"""A soft PLC and its Modbus server, wired for one Modbus flavor: OpenPLC's map (the server
reads and writes the image itself) or the CODESYS layout (a
:class:`~armbench.softplc.codesys_device.CodesysDevice` between them, which the scan cycle
copies in and out)."""

from __future__ import annotations

from typing import Any

from .codesys_device import CodesysDevice
from .fastpath import new_scan_lock
from .loader import LoadedProgram
from .modbus_map import CODESYS, Flavor, flavor
from .modbus_server import ModbusServer
from .scan import SoftPlc


def soft_plc(program: LoadedProgram, modbus_flavor: str | Flavor = "openplc",
             **server_options: Any) -> tuple[SoftPlc, ModbusServer]:
    """A (stopped) soft PLC running ``program`` and a (not yet started) Modbus server for it
    serving ``modbus_flavor``'s layout; ``server_options`` go to :class:`ModbusServer`
    (host, port, max_clients, idle_timeout_s)."""
    if flavor(modbus_flavor) == CODESYS:
        lock = new_scan_lock()
        device = CodesysDevice.for_program(program.module.program, program.image, lock)
        plc = SoftPlc(program, lock=lock, io=device)
        return plc, ModbusServer(program.image, lock, device=device, **server_options)
    plc = SoftPlc(program)
    return plc, ModbusServer(program.image, plc.lock, **server_options)
