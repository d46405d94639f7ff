"""A soft PLC and its Modbus server, wired for one Modbus flavor: OpenPLC v3's map (the server
reads and writes the image itself), OpenPLC v4's Modbus plugin (an
:class:`~armbench.softplc.openplc_v4.OpenPlcV4Device` with its segments and write journal,
which the scan cycle drains and commits around each scan) or the CODESYS layout (a
:class:`~armbench.softplc.codesys_device.CodesysDevice` between them, which the scan cycle
copies in and out)."""

from __future__ import annotations

from typing import Any

from .codesys_device import CodesysDevice
from .fastpath import new_scan_lock
from .loader import LoadedProgram
from .modbus_map import CODESYS, OPENPLC_V4, Flavor, flavor
from .modbus_server import ModbusServer
from .openplc_v4 import OpenPlcV4Device, V4Settings, v3_map_problems
from .scan import SoftPlc


def located_addresses(program: LoadedProgram) -> list[str]:
    """The direct addresses of the program's located variables (every one, the ones Modbus
    does not reach included: they size v4's image too)."""
    from ..registermap import program_map

    pm = program_map(program.module.program)
    return [r.declared or r.location for r in pm.registers] + \
        [u.location for u in pm.unreachable]


def soft_plc(program: LoadedProgram, modbus_flavor: str | Flavor = "openplc",
             v4: V4Settings | None = None, **server_options: Any) -> tuple[SoftPlc, ModbusServer]:
    """A (stopped) soft PLC running ``program`` and a (not yet started) Modbus server for it
    serving as ``modbus_flavor``'s server does; ``server_options`` go to :class:`ModbusServer`
    (host, port, max_clients, idle_timeout_s). ``v4``: how OpenPLC v4 is set up (default: the
    Modbus counts that keep every variable at its v3 address, armbench.softplc.openplc_v4);
    ValueError when those would move a variable or cannot be served."""
    fl = flavor(modbus_flavor)
    if fl == CODESYS:
        lock = new_scan_lock()
        device = CodesysDevice.for_program(program.module.program, program.image, lock)
        plc = SoftPlc(program, lock=lock, io=device)
        return plc, ModbusServer(program.image, lock, device=device, **server_options)
    if fl == OPENPLC_V4:
        settings = v4 or V4Settings()
        locations = located_addresses(program)
        segments = settings.segments(locations)
        problems = v3_map_problems(segments, locations)
        if problems:
            raise ValueError("these OpenPLC v4 Modbus counts do not keep the program's "
                             "variables at their v3 addresses: " + "; ".join(problems))
        lock = new_scan_lock()
        v4_device = OpenPlcV4Device(program.image, lock, segments, settings.journal_capacity)
        plc = SoftPlc(program, lock=lock, io=v4_device)
        return plc, ModbusServer(program.image, lock, device=v4_device, **server_options)
    if v4 is not None:
        raise ValueError(f"v4 settings given for the {fl.name} flavor")
    plc = SoftPlc(program)
    return plc, ModbusServer(program.image, plc.lock, **server_options)
