"""PlcFault: a runtime fault of compiled ST (division by zero, bounds, watchdog) with its place."""

from __future__ import annotations


class PlcFault(Exception):
    """The PLC code faulted; `location` is the ST position `file.st:line:col`."""

    def __init__(self, message: str, location: str) -> None:
        super().__init__(f"{location}: PLC fault: {message}")
        self.message = message
        self.location = location
