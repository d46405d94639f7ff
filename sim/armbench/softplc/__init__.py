"""Soft PLC runtime: process image, scan cycle and Modbus TCP server.

The pymodbus client lives in :mod:`armbench.softplc.modbus_client` and is deliberately not
imported here, so using the runtime does not pull in pymodbus.
"""

from .fastpath import ImageLock
from .image import IMAGE_SIZE, ProcessImage
from .modbus_server import ModbusServer, PduHandler
from .program import CompiledProgram, PlcFault, TaskSpec
from .scan import Distribution, FaultInfo, PlcState, SoftPlc, TaskStats

__all__ = [
    "IMAGE_SIZE",
    "CompiledProgram",
    "Distribution",
    "FaultInfo",
    "ImageLock",
    "ModbusServer",
    "PduHandler",
    "PlcFault",
    "PlcState",
    "ProcessImage",
    "SoftPlc",
    "TaskSpec",
    "TaskStats",
]
