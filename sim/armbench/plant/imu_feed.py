"""Feed simulated IMU samples (armbench.plant.imu) into the soft PLC's input registers.

Why not over Modbus: OpenPLC's input registers (%IW) are read-only over Modbus (function 4
reads them, no function writes them), on the real runtime and on the soft PLC alike. On a
Raspberry Pi the PSM (the runtime's Python I/O layer) writes them once per scan; on the bench
the plant plays that part and writes the soft PLC's process image directly, under the scan
lock, exactly where the PSM's values land. So feeding inputs needs the in-process soft PLC
(:class:`armbench.softplc.scan.SoftPlc`), not a Modbus connection; commands and results still
go over Modbus (``ArmControllerClient.imu_*``).

Protocol (Controller.st, IMU COMMANDS): the nine raw words go to %IW0..8, then the sample
counter %IW9 is incremented; the PLC filters a sample once, when it sees the counter change.
:meth:`ImuFeeder.feed` waits until the PLC has taken the sample (ImuLastSeq shows its
counter), so a test feeds every sample exactly once whatever the scan rate.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from armbench.plant.imu import ImuRecord
from armbench.registermap import controller_map
from armbench.softplc.fastpath import ImageLock
from armbench.softplc.image import ProcessImage

_RAW_NAMES = ("ImuGyroX", "ImuGyroY", "ImuGyroZ", "ImuAccelX", "ImuAccelY", "ImuAccelZ",
              "ImuMagX", "ImuMagY", "ImuMagZ")


class ImuFeedTimeout(TimeoutError):
    """The PLC did not take a sample in time (is its scan running?)."""


@dataclass
class ImuFeeder:
    """Writes raw samples into ``image`` (the soft PLC's process image) under ``lock``."""

    image: ProcessImage
    lock: threading.Lock | ImageLock  # SoftPlc.lock (an ImageLock with the C fast path)
    timeout_s: float = 5.0
    seq: int = 0  # the counter value of the last sample written
    _raw_iw: tuple[int, ...] = field(init=False)
    _seq_iw: int = field(init=False)
    _taken_md: int = field(init=False)

    def __post_init__(self) -> None:
        cmap = controller_map()
        self._raw_iw = tuple(cmap[n.upper()].index for n in _RAW_NAMES)
        self._seq_iw = cmap["IMUSAMPLESEQ"].index
        self._taken_md = cmap["IMULASTSEQ"].index

    def write(self, raw: Sequence[int]) -> int:
        """Write one sample (gyro x/y/z, accel x/y/z, mag x/y/z as the chips' signed 16-bit
        values) and bump the counter; returns the counter value. Does not wait."""
        if len(raw) != len(_RAW_NAMES):
            raise ValueError(f"an IMU sample has {len(_RAW_NAMES)} values, got {len(raw)}")
        words = []
        for name, v in zip(_RAW_NAMES, raw, strict=True):
            if not -32768 <= int(v) <= 32767:
                raise ValueError(f"{name} must be a signed 16-bit value, got {v}")
            words.append(int(v) & 0xFFFF)
        self.seq = (self.seq + 1) & 0xFFFF
        with self.lock:
            for iw, w in zip(self._raw_iw, words, strict=True):
                self.image.iw[iw] = w
            self.image.iw[self._seq_iw] = self.seq
        return self.seq

    def taken(self) -> bool:
        """True when the PLC has filtered the last written sample."""
        with self.lock:
            return self.image.md[self._taken_md] == self.seq

    def feed(self, raw: Sequence[int]) -> None:
        """Write one sample and wait until the PLC has filtered it."""
        self.write(raw)
        deadline = time.monotonic() + self.timeout_s
        while not self.taken():
            if time.monotonic() > deadline:
                raise ImuFeedTimeout(f"the PLC did not take IMU sample {self.seq} within "
                                     f"{self.timeout_s} s: is the soft PLC scanning?")
            time.sleep(0.0001)

    def feed_record(self, record: ImuRecord, start: int = 0, stop: int | None = None) -> None:
        """Feed the record's samples start..stop-1 one by one."""
        for k in range(start, len(record) if stop is None else stop):
            g, a, m = record.gyro_raw[k], record.accel_raw[k], record.mag_raw[k]
            self.feed([int(g[0]), int(g[1]), int(g[2]), int(a[0]), int(a[1]), int(a[2]),
                       int(m[0]), int(m[1]), int(m[2])])
