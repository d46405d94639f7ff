"""The Modbus suite's fixtures (``plc``, ``plc_address``) and options (``--plc-host``,
``--plc-port``) come from the armbench pytest plugin: sim/armbench/harness/pytest_plugin.py."""
