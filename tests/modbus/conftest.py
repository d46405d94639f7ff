"""The Modbus suite's fixtures (``plc``, ``plc_address``, ``plc_flavor``) and options
(``--plc-host``, ``--plc-port``, ``--plc-flavor``) come from the armbench pytest plugin:
sim/armbench/harness/pytest_plugin.py.

A module marked ``openplc_only`` checks what only OpenPLC v3's server does (its answers to
edge-case requests), one marked ``openplc_v4_only`` what only OpenPLC v4's Modbus plugin does
(its segments sized to the program, its write journal): each is skipped, saying so, when the
session speaks another flavor."""

from __future__ import annotations

import pytest

from armbench.harness.pytest_plugin import flavor_name

ONLY = {"openplc_only": "openplc", "openplc_v4_only": "openplc-v4"}
WHERE = {"openplc": "OpenPLC v3's server (docs/modbus-parity.md)",
         "openplc-v4": "OpenPLC v4's Modbus plugin (tests/softplc/test_v4_modbus_flavor.py "
                       "pins its model)",
         "codesys": "the CODESYS layout's server, which follows the Modbus specification "
                    "(tests/softplc/test_softplc_codesys_device.py)"}


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "openplc_only: checks OpenPLC v3's own Modbus server; "
                                       "skipped under another --plc-flavor")
    config.addinivalue_line("markers", "openplc_v4_only: checks OpenPLC v4's Modbus plugin; "
                                       "skipped unless --plc-flavor openplc-v4")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    flavor = flavor_name(config)
    for marker, only in ONLY.items():
        if flavor == only:
            continue
        skip = pytest.mark.skip(reason=f"{only} only; this session speaks {WHERE[flavor]}")
        for item in items:
            if item.get_closest_marker(marker) is not None:
                item.add_marker(skip)
