"""What the v4 plugin tests share besides the stand-ins (v4_standin): a fake clock, the
loaded plugin's modules, and a rig of stand-in runtime args, chip models and bus to step the
plugin's loops by hand. The fixtures that build them are in this folder's conftest.py."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from v4_standin import RuntimeTree, SimI2CBus, StandInRuntime

from armbench.plant.imu_chips import Gy87Board
from armbench.plant.pca9685 import PCA9685

ADDR = 0x40
PRESCALE = 121  # what the controller publishes at %MD14 for 50 Hz


@dataclass
class FakeClock:
    """Monotonic seconds that pass only when told (the driver's 500 us wait included)."""

    t: float = 1000.0

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        self.t += dt

    def sleep(self, dt: float) -> None:
        """time.sleep as the plugin sees it: never shorter than asked, a little longer."""
        self.t += dt + 1e-6


@dataclass
class Loaded:
    tree: RuntimeTree
    module: ModuleType
    shared: ModuleType
    smbus2: ModuleType
    psm: ModuleType


@dataclass
class Rig:
    """Stand-in runtime args over a zeroed image with the controller's locations, a PCA9685
    and a GY-87 board on simulated bus 1, a fake clock; ``plugin()`` builds the plugin's
    ArmIoPlugin over them (what init() builds), to be stepped by hand."""

    loaded: Loaded
    runtime: StandInRuntime
    chip: PCA9685
    board: Gy87Board
    bus: SimI2CBus
    clock: FakeClock
    settings: dict[str, Any] = field(default_factory=dict)

    def plugin(self, **overrides: Any) -> Any:
        raw = json.loads(self.loaded.tree.config_file.read_text())
        raw.update(overrides)
        module, shared = self.loaded.module, self.loaded.shared
        settings, unknown = module.Settings.from_map(raw, self.loaded.psm)
        assert unknown == []
        sink = module.runtime_log_sink(shared.PluginLogger(module.LOG_NAME, self.runtime))
        return module.ArmIoPlugin.create(self.loaded.psm, settings,
                                         shared.SafeBufferAccess(self.runtime), sink,
                                         clock=self.clock, sleep=self.clock.sleep)

    def scan(self) -> None:
        """What a scan does to the plugin's writes: the drain at its start."""
        with self.runtime.lock:
            self.runtime.drain()

    def step(self, plugin: Any, n: int = 1, dt: float = 0.005) -> None:
        """n periods of the plugin, a scan between each."""
        for _ in range(n):
            self.clock.advance(dt)
            plugin.step(self.clock())
            self.scan()

    def words(self, **channels: int) -> None:
        """The program's channel words, e.g. words(ch0=307, ch1=4096)."""
        for name, value in channels.items():
            self.runtime.set(f"%QW{int(name.removeprefix('ch'))}", value)

    def flags(self) -> tuple[bool, bool]:
        """(PwmDriverReady %IX0.0, PwmDriverFault %IX0.1) as the program sees them."""
        return bool(self.runtime.get("%IX0.0")), bool(self.runtime.get("%IX0.1"))

    def shown(self) -> list[str]:
        return self.runtime.shown()


