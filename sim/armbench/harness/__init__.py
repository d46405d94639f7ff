"""Test harness for Modbus regression suites (a pytest plugin, registered as `armbench`)."""
