"""Fixtures of the v4 plugin tests: the stand-in runtime tree with the plugin installed and
loaded as the runtime loads it, and a rig of stand-in runtime args, chip models and bus
(v4_standin's module docstring says what each stand-in is; v4_rig holds the classes)."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from v4_rig import ADDR, PRESCALE, FakeClock, Loaded, Rig
from v4_standin import (
    RuntimeTree,
    SimI2CBus,
    StandInRuntime,
    controller_locations,
    load_plugin,
    unload,
)

from armbench.plant.imu_chips import Gy87Board
from armbench.plant.pca9685 import PCA9685
from armbench.softplc.image import ProcessImage


@pytest.fixture
def loaded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Loaded]:
    """The plugin installed in a stand-in runtime tree and imported as the runtime imports
    it, from the runtime's root as working directory; unloaded again afterwards (the
    modules, sys.path) so that other tests see no smbus2 or shared."""
    saved = list(sys.path)
    tree = RuntimeTree(tmp_path / "openplc-runtime")
    monkeypatch.chdir(tree.root)
    module = load_plugin(tree)
    try:
        shared = module.import_shared(str(tree.plugin_dir))
        import smbus2

        smbus2.BUSES.clear()
        psm = module.load_psm(str(tree.plugin_dir))
        yield Loaded(tree, module, shared, smbus2, psm)
    finally:
        try:
            module.cleanup()
        finally:
            unload(saved)


@pytest.fixture
def rig(loaded: Loaded) -> Rig:
    runtime = StandInRuntime(ProcessImage.allocate(), controller_locations(),
                             config_path=loaded.tree.line.config_path)
    clock = FakeClock()
    chip = PCA9685(address=ADDR)
    board = Gy87Board()
    bus = SimI2CBus(pca=chip, imu=board, clock=clock)
    loaded.smbus2.BUSES[1] = bus
    rig = Rig(loaded, runtime, chip, board, bus, clock)
    # the runtime hands the table lengths to set_image_sizes before init()
    assert loaded.module.set_image_sizes(runtime.image_sizes()) == 0
    for ch in range(16):
        runtime.set(f"%QW{ch}", 0x1000)  # the controller at power-up: every channel off
    runtime.set("%MD14", PRESCALE)
    return rig
