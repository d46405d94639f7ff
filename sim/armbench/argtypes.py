"""argparse value types shared by the command line, the demo and the pytest plugin: a bad
value is a one-line usage error naming the option, never a traceback later on."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def port(text: str) -> int:
    """A TCP port, 0..65535 (0: any free port)."""
    value = _int(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"port must be 0..65535, got {value}")
    return value


def count(text: str) -> int:
    """A count that may be zero: 0, 1, 2, ..."""
    return _at_least(_int(text), 0)


def positive_count(text: str) -> int:
    """A count of at least one."""
    return _at_least(_int(text), 1)


def _at_least(value: int, low: int) -> int:
    if value < low:
        raise argparse.ArgumentTypeError(f"must be {low} or more, got {value}")
    return value


def seconds(text: str) -> float:
    """A finite duration, 0 or more."""
    value = _float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text}")
    return value


def positive_seconds(text: str) -> float:
    """A finite duration above zero."""
    value = _float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be a number of seconds above 0, got {text}")
    return value


def positive_length(text: str) -> float:
    """A finite length above zero."""
    value = _float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be above 0, got {text}")
    return value


def update_rate(text: str) -> float:
    """An update rate in Hz, 1..1000."""
    value = _float(text)
    if not 1.0 <= value <= 1000.0:
        raise argparse.ArgumentTypeError(f"must be 1..1000 Hz, got {text}")
    return value


def float_between(low: float, high: float, unit: str) -> Callable[[str], float]:
    """A finite number within low..high (unit: for the message)."""
    def parse(text: str) -> float:
        value = _float(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must lie in {low:g}..{high:g} {unit}, "
                                             f"got {value:g}")
        return value
    return parse


def finite(text: str) -> float:
    """Any finite number."""
    return _float(text)


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None


def _float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def plc_addresses(text: str) -> tuple[tuple[str, int], ...]:
    """A comma-separated list of PLC addresses, ``host:port`` or ``host`` (port 502); an IPv6
    host goes in brackets, ``[::1]:5020``."""
    out: list[tuple[str, int]] = []
    for item in text.split(","):
        item = item.strip()
        host, sep, port_text = item.rpartition(":")
        if not sep or (host.count(":") and not host.startswith("[")):
            host, port_text = item, "502"  # no port, or a bare IPv6 address
        host = host.removeprefix("[").removesuffix("]")
        if not host:
            raise argparse.ArgumentTypeError(f"no host in {item!r} (want host:port)")
        out.append((host, port(port_text)))
    return tuple(out)


# OpenPLC v4's Modbus server counts (armbench.softplc.openplc_v4.DEFAULT_COUNTS; not imported
# here: the pytest plugin imports this module and must stay cheap)
V4_COUNT_KEYS = ("qw_count", "mw_count", "md_count", "ml_count", "qx_bits", "mx_bits",
                 "ix_bits", "iw_count")


def v4_counts(text: str) -> dict[str, int]:
    """``KEY=N,KEY=N``: OpenPLC v4 Modbus server counts (``qw_count=1024,mw_count=1024``)."""
    counts: dict[str, int] = {}
    for item in text.split(","):
        key, sep, value = item.strip().partition("=")
        if not sep or key not in V4_COUNT_KEYS:
            raise argparse.ArgumentTypeError(f"{item.strip()!r}: want KEY=N with KEY one of "
                                             f"{', '.join(V4_COUNT_KEYS)}")
        counts[key] = _at_least(_int(value), 0)
    return counts
