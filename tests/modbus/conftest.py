"""The Modbus suite's fixtures (``plc``, ``plc_address``, ``plc_flavor``) and options
(``--plc-host``, ``--plc-port``, ``--plc-flavor``) come from the armbench pytest plugin:
sim/armbench/harness/pytest_plugin.py.

A module marked ``openplc_only`` checks what only OpenPLC's server does (its answers to
edge-case requests): it is skipped, saying so, when the session speaks another flavor."""

from __future__ import annotations

import pytest

from armbench.harness.pytest_plugin import flavor_name


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "openplc_only: checks OpenPLC v3's own Modbus server; "
                                       "skipped under --plc-flavor codesys")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    flavor = flavor_name(config)
    if flavor == "openplc":
        return
    skip = pytest.mark.skip(reason=f"OpenPLC v3's server only; the {flavor} layout's server "
                                   "follows the Modbus specification "
                                   "(tests/softplc/test_softplc_codesys_device.py)")
    for item in items:
        if item.get_closest_marker("openplc_only") is not None:
            item.add_marker(skip)
