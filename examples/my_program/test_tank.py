"""Tests of tank.st through the armbench pytest plugin: each runs against a soft PLC running
the program (the default) or against a real PLC running it (--plc-address HOST:PORT), and
reaches the program's located variables by name with their declared types."""

import pytest

from armbench.harness.program import PlcProgram, PlcVariables
from armbench.softplc.modbus_client import PlcClient


@pytest.fixture(autouse=True)
def settings(plc_vars: PlcVariables) -> None:
    """Every test starts from the program's own settings, the pump off and the tank half full."""
    plc_vars.write(LowPct=20.0, HighPct=80.0, AlarmPct=95.0, LevelPct=50.0, Enable=False)
    plc_vars.wait_scans(1)
    plc_vars["Enable"] = True
    plc_vars.wait_scans(1)


def test_pump_starts_at_the_low_level(plc_vars: PlcVariables) -> None:
    starts = plc_vars["PumpStarts"]
    plc_vars["LevelPct"] = 20.0
    plc_vars.wait_scans(1)
    assert plc_vars["Pump"] is True
    assert plc_vars["Mode"] == 1
    assert plc_vars["PumpStarts"] == starts + 1


def test_hysteresis_between_the_levels(plc_vars: PlcVariables) -> None:
    plc_vars["LevelPct"] = 10.0
    plc_vars.wait_scans(1)
    plc_vars["LevelPct"] = 50.0  # rising through the band: keeps filling
    plc_vars.wait_scans(3)
    assert plc_vars["Pump"] is True
    plc_vars["LevelPct"] = 80.0
    plc_vars.wait_scans(1)
    assert plc_vars["Pump"] is False
    plc_vars["LevelPct"] = 50.0  # falling through the band: stays off
    plc_vars.wait_scans(3)
    assert plc_vars["Pump"] is False
    assert plc_vars["Mode"] == 2


def test_alarm_at_the_alarm_level(plc_vars: PlcVariables) -> None:
    plc_vars["LevelPct"] = 94.9
    plc_vars.wait_scans(1)
    assert plc_vars["Alarm"] is False
    plc_vars["LevelPct"] = 95.0
    plc_vars.wait_scans(1)
    assert plc_vars["Alarm"] is True


def test_disabled_pump_stays_off(plc_vars: PlcVariables) -> None:
    plc_vars.write(Enable=False, LevelPct=5.0)  # one request: no scan sees only one of them
    plc_vars.wait_scans(2)
    assert plc_vars["Pump"] is False
    assert plc_vars["Mode"] == 0


def test_bad_settings_keep_the_pump_off(plc_vars: PlcVariables) -> None:
    plc_vars.write(LowPct=70.0, HighPct=30.0, LevelPct=5.0)
    plc_vars.wait_scans(1)
    assert plc_vars["SettingsOk"] is False
    assert plc_vars["Pump"] is False
    assert plc_vars["Mode"] == -1


def test_the_raw_modbus_view(modbus: PlcClient, plc_program: PlcProgram,
                            plc_flavor: str) -> None:
    """The same variables as a plain Modbus client sees them (OpenPLC's map)."""
    if plc_flavor != "openplc":
        pytest.skip("reads OpenPLC's addresses; a CODESYS PLC has the map "
                    "`armbench export` writes beside its XML")
    level = plc_program.variable("LevelPct")
    assert (level.location, level.table, level.address) == ("%MD2", "holding", 2052)
    assert modbus.read_real(2) == 50.0  # %MD2 as a REAL, most significant word first
    assert modbus.read_coils(0, 4) == [True, False, False, True]  # %QX0.0 .. %QX0.3
