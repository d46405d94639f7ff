"""``armbench demo-imu``: the simulated hand drives the 5-axis arm over Modbus (FollowImu,
Controller.st IMU COMMANDS 46; document 004).

The soft PLC runs the controller's 10 ms task in simulated time (as fast as the host allows).
Before every scan a :class:`HandRig` does what the PSM does on a Raspberry Pi: it writes the
next raw sample of the simulated MPU6050/HMC5883L (armbench.plant.imu) into %IW0..9, one sample
per scan (100 Hz), and it records the slew limiter's five joint outputs of the scan before.
A Modbus client (ArmControllerClient) moves the arm to its start pose, sets up the filter and
starts FollowImu; the per-second figures compare the hand's ground-truth tool direction (the
trajectory's own quaternion, turned into the arm's base frame) with the arm's tool direction,
computed here by a closed-form FK of the recorded joint outputs, independent of the ST code.
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np
import numpy.typing as npt

from . import argtypes
from .controller_client import ERR_OK, ArmControllerClient, CommandRejected
from .plant.arm import DEFAULT_GEOMETRY, ArmGeometry
from .plant.imu import HandTrajectory, ImuModel, ImuRecord, quat_to_matrix, simulate
from .plant.imu_feed import ImuFeeder
from .registermap import SOURCES, controller_map
from .softplc.fastpath import ImageLock
from .softplc.image import ProcessImage
from .softplc.loader import load_program
from .softplc.modbus_client import PlcClient
from .softplc.modbus_server import ModbusServer
from .softplc.scan import SoftPlc

FloatArray = npt.NDArray[np.float64]

TOOL_MM = 60.0  # FiveAxisGeometry's ToolMm, which the controller uses
SCAN_S = 0.01  # the controller's TASK INTERVAL
TASK_NS = 10_000_000
# Start pose: tool horizontal along the base X axis (pitch 0, roll 0) with
# Shoulder 75 and Elbow 95 (forearm 10 deg down, wrist +10): tool pitch -40..+35 deg stays
# within every servo's travel with the tip held.
START_TIP_MM = (239.08, 0.0, 193.34)
_OUT_NAMES = ("OUTBASEDEG", "OUTSHOULDERDEG", "OUTELBOWDEG", "OUTWRISTPITCHDEG",
              "OUTWRISTROLLDEG")
_SET_NAMES = ("SETBASEDEG", "SETSHOULDERDEG", "SETELBOWDEG", "SETWRISTPITCHDEG",
              "SETWRISTROLLDEG")


class DemoError(RuntimeError):
    """The controller refused a step of the demo (the message names the command)."""


def demo_trajectory(heading_deg: float) -> HandTrajectory:
    """Tilts (pitch) and turns (roll about the tool axis) of a hand facing the arm's X axis:
    yaw = ``heading_deg``, so its tool direction stays in the arm plane of the start pose."""
    return HandTrajectory(roll=((35.0, 0.12, 0.0), (10.0, 0.41, 1.0)),
                          pitch=((20.0, 0.09, 0.0), (6.0, 0.33, 2.0)),
                          yaw=(), yaw_offset_deg=heading_deg)


# ----- closed-form references (numpy, independent of st/) -----

def arm_frames(joints_deg: FloatArray, geometry: ArmGeometry = DEFAULT_GEOMETRY,
               tool_mm: float = TOOL_MM) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Tool direction, the tool frame's y axis and the tool tip (mm) of joint rows
    (Base, Shoulder, Elbow, WristPitch, WristRoll; deg), N x 3 each. Tool pitch = Shoulder +
    Elbow - 180 + WristPitch; the frame is Rz(Base) Ry(-pitch) Rx(roll)."""
    j = np.radians(np.atleast_2d(joints_deg))
    b, s, e, wp, wr = (j[:, i] for i in range(5))
    fore = s + e - math.pi
    p = fore + wp
    cb, sb, cp, sp = np.cos(b), np.sin(b), np.cos(p), np.sin(p)
    x = np.stack([cp * cb, cp * sb, sp], axis=1)
    n = np.stack([-sb, cb, np.zeros_like(b)], axis=1)  # the arm plane's normal
    z0 = np.cross(x, n)
    y = np.cos(wr)[:, None] * n + np.sin(wr)[:, None] * z0
    radial = geometry.a2 + geometry.a3 * np.cos(s) + geometry.a4 * np.cos(fore)
    height = geometry.a1 + geometry.a3 * np.sin(s) + geometry.a4 * np.sin(fore)
    flange = np.stack([radial * cb, radial * sb, height], axis=1)
    return x, y, flange + tool_mm * x


def earth_to_base(vectors: FloatArray, heading_deg: float) -> FloatArray:
    """v_base = Rz(-heading) v_earth: the arm's X axis points ``heading_deg`` counter-clockwise
    (about Z up) from magnetic north, the filters' earth X."""
    h = math.radians(heading_deg)
    rot = np.array([[math.cos(h), math.sin(h), 0.0], [-math.sin(h), math.cos(h), 0.0],
                    [0.0, 0.0, 1.0]])
    return np.asarray(np.atleast_2d(vectors) @ rot.T, dtype=np.float64)


def pitch_roll_in_plane(x: FloatArray, y: FloatArray, plane_deg: float
                        ) -> tuple[FloatArray, FloatArray]:
    """Tool pitch (angle of x above the radial axis of the vertical plane at azimuth
    ``plane_deg``) and roll (of y about x, from the plane's normal), deg, of base-frame axes."""
    a = math.radians(plane_deg)
    u = np.array([math.cos(a), math.sin(a), 0.0])
    n = np.array([-math.sin(a), math.cos(a), 0.0])
    pitch = np.arctan2(x[:, 2], x @ u)
    xp = np.cos(pitch)[:, None] * u + np.sin(pitch)[:, None] * np.array([0.0, 0.0, 1.0])
    z0 = np.cross(xp, n)
    roll = np.arctan2(np.sum(y * z0, axis=1), y @ n)
    return np.degrees(pitch), np.degrees(roll)


def angle_deg(a: FloatArray, b: FloatArray) -> FloatArray:
    """Angle between unit vectors, row by row, deg."""
    c = np.clip(np.sum(a * b, axis=1), -1.0, 1.0)
    return np.asarray(np.degrees(np.arccos(c)), dtype=np.float64)


# ----- the rig: one sample per scan in, the joint outputs out -----

@dataclass
class ScanRow:
    sample: int  # index of the last sample written before the scan (-1: none yet)
    joints: tuple[float, ...]  # deg, slew limiter outputs after the scan
    setpoints: tuple[float, ...] = ()  # deg, the motion group's setpoints (limiter input)
    follow_state: int = 0  # FollowState after the scan: 0 off, 1 following, 2 braking


@dataclass
class HandRig:
    """Call :meth:`before_scan` before every scan of the soft PLC (in its scan thread): it
    records the outputs of the scan just run and writes the next sample while playing."""

    image: ProcessImage
    lock: threading.Lock | ImageLock
    feeder: ImuFeeder = field(init=False)
    record: ImuRecord | None = None
    scans_per_sample: int = 1  # 1 = 100 Hz samples at the 10 ms task, 2 = 50 Hz, ...
    next_index: int = 0
    playing: bool = False
    recording: bool = False
    rows: list[ScanRow] = field(default_factory=list)
    _out_md: tuple[int, ...] = field(init=False)
    _set_md: tuple[int, ...] = field(init=False)
    _state_md: int = field(init=False)
    _mutex: threading.Lock = field(default_factory=threading.Lock)
    _scans: int = 0

    def __post_init__(self) -> None:
        self.feeder = ImuFeeder(self.image, self.lock)
        with self.lock:  # continue the sample counter where the PLC stands
            self.feeder.seq = self.image.iw[controller_map()["IMUSAMPLESEQ"].index]
        cmap = controller_map()
        self._out_md = tuple(cmap[n].index for n in _OUT_NAMES)
        self._set_md = tuple(cmap[n].index for n in _SET_NAMES)
        self._state_md = cmap["FOLLOWSTATE"].index

    def play(self, record: ImuRecord, start: int = 0, scans_per_sample: int = 1) -> None:
        if not 1 <= scans_per_sample <= 100:
            raise ValueError(f"scans_per_sample must lie in 1..100, got {scans_per_sample}")
        with self._mutex:
            self.record, self.next_index, self.playing = record, start, True
            self.scans_per_sample = scans_per_sample

    def pause(self) -> None:
        with self._mutex:
            self.playing = False

    def start_recording(self) -> None:
        with self._mutex:
            self.rows, self.recording = [], True

    def take_rows(self) -> list[ScanRow]:
        with self._mutex:
            self.recording = False
            return list(self.rows)

    @property
    def scans(self) -> int:
        return self._scans

    def outputs(self) -> tuple[float, ...]:
        """The slew limiter's five joint outputs, deg."""
        return self._floats(self._out_md)

    def setpoints(self) -> tuple[float, ...]:
        """The motion group's five joint setpoints, deg."""
        return self._floats(self._set_md)

    def _floats(self, md: tuple[int, ...]) -> tuple[float, ...]:
        with self.lock:
            words = [self.image.md[i] for i in md]
        return struct.unpack(f"<{len(words)}f", struct.pack(f"<{len(words)}I", *words))

    def wait_samples(self, index: int, timeout_s: float = 60.0) -> None:
        """Block until the sample ``index`` has been written (or playing stopped)."""
        deadline = time.monotonic() + timeout_s
        while self.playing and self.next_index <= index:
            if time.monotonic() > deadline:
                raise DemoError(f"sample {index} not written within {timeout_s} s")
            time.sleep(0.002)

    def before_scan(self) -> None:
        self._scans += 1
        with self._mutex:
            if self.recording:
                with self.lock:
                    state = self.image.md[self._state_md]
                self.rows.append(ScanRow(self.next_index - 1, self.outputs(),
                                         self.setpoints(), state))
            rec = self.record
            if self.playing and rec is not None and self._scans % self.scans_per_sample == 0:
                if self.next_index >= len(rec):
                    self.playing = False
                else:
                    k = self.next_index
                    g, a, m = rec.gyro_raw[k], rec.accel_raw[k], rec.mag_raw[k]
                    self.feeder.write([int(g[0]), int(g[1]), int(g[2]), int(a[0]), int(a[1]),
                                       int(a[2]), int(m[0]), int(m[1]), int(m[2])])
                    self.next_index = k + 1


@dataclass
class PacedController:
    plc: SoftPlc
    address: tuple[str, int]
    rig: HandRig


@contextmanager
def paced_controller(pause_s: float = 0.0002) -> Iterator[PacedController]:
    """The controller on a soft PLC stepped in simulated time with a HandRig before every
    scan, and its Modbus server on a free loopback port; stops both on exit."""
    prog = load_program(list(SOURCES))
    plc = SoftPlc(prog)
    server = ModbusServer(prog.image, plc.lock, port=0)
    server.start()
    rig = HandRig(prog.image, plc.lock)
    stop = threading.Event()

    def run() -> None:
        now = 0
        plc.run()
        while not stop.is_set():
            rig.before_scan()
            plc.step(now)
            now += TASK_NS
            time.sleep(pause_s)  # room for the Modbus threads

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield PacedController(plc, ("127.0.0.1", server.port), rig)
    finally:
        stop.set()
        thread.join(5.0)
        server.stop()


# ----- one follow run and its figures -----

@dataclass
class FollowRun:
    t: FloatArray  # s since the follow started, per recorded scan
    hand_dir: FloatArray  # N x 3, ground truth, base frame
    arm_dir: FloatArray  # N x 3, FK of the joint outputs
    hand_pitch: FloatArray  # deg, in the arm plane
    hand_roll: FloatArray
    arm_pitch: FloatArray
    arm_roll: FloatArray
    error_deg: FloatArray  # angle between hand_dir and arm_dir
    drift_mm: FloatArray  # held point (tip or flange) from where it stood at the start
    joints: FloatArray  # N x 5 deg
    setpoints: FloatArray  # N x 5 deg, the group's setpoints the follow wrote
    flange_fixed: bool
    heading_deg: float
    rate_hz: float


def analyse(rows: Sequence[ScanRow], record: ImuRecord, heading_deg: float,
            flange_fixed: bool, geometry: ArmGeometry = DEFAULT_GEOMETRY) -> FollowRun:
    """The figures of a recorded follow: row 0 is the first scan after the start."""
    if not rows:
        raise DemoError("no scans recorded")
    joints = np.array([r.joints for r in rows], dtype=np.float64)
    idx = np.clip(np.array([r.sample for r in rows]), 0, len(record) - 1)
    rot = quat_to_matrix(record.quat_true[idx])
    hand_x = earth_to_base(rot[:, :, 0], heading_deg)
    hand_y = earth_to_base(rot[:, :, 1], heading_deg)
    arm_x, arm_y, tip = arm_frames(joints, geometry)
    held = tip - TOOL_MM * arm_x if flange_fixed else tip
    plane = math.degrees(math.atan2(held[0, 1], held[0, 0]))
    hp, hr = pitch_roll_in_plane(hand_x, hand_y, plane)
    ap, ar = pitch_roll_in_plane(arm_x, arm_y, plane)
    t = np.arange(len(rows), dtype=np.float64) * SCAN_S
    return FollowRun(t=t, hand_dir=hand_x, arm_dir=arm_x, hand_pitch=hp, hand_roll=hr,
                     arm_pitch=ap, arm_roll=ar,
                     error_deg=angle_deg(hand_x, arm_x),
                     drift_mm=np.linalg.norm(held - held[0], axis=1), joints=joints,
                     setpoints=np.array([r.setpoints for r in rows], dtype=np.float64),
                     flange_fixed=flange_fixed, heading_deg=heading_deg,
                     rate_hz=1.0 / record.period_s)


def _check(what: str, code: int) -> None:
    if code != ERR_OK:
        raise CommandRejected(what, code)


def scans_per_sample(rate_hz: float) -> int:
    """Scans between two IMU samples at ``rate_hz``: the 10 ms scan writes the samples, so
    the rate must be 100 Hz divided by a whole number (DemoError otherwise)."""
    spacing = 1.0 / (rate_hz * SCAN_S) if rate_hz > 0.0 and math.isfinite(rate_hz) else 0.0
    if not (spacing >= 1.0 and math.isclose(spacing, round(spacing))):
        raise DemoError(f"the IMU rate must be 100 Hz divided by a whole number (100, 50, "
                        f"25, ...), got {rate_hz:g} Hz")
    return round(spacing)


def run_follow(address: tuple[str, int], rig: HandRig, *, duration_s: float = 20.0,
               heading_deg: float = 10.0, flange_fixed: bool = False, seed: int = 5,
               lead_s: float = 0.5, trajectory: HandTrajectory | None = None,
               rate_hz: float = 100.0, max_jerk_dps3: int = 0) -> FollowRun:
    """Start pose, Madgwick MARG filter started at the hand's true orientation, ``lead_s`` of
    samples, then FollowImu for ``duration_s`` while the hand moves; returns the figures.
    ``rate_hz``: the IMU's sample rate, 100 Hz divided by a whole number of scans;
    ``max_jerk_dps3``: FollowImu's jerk limit of the turning speed (0 = none)."""
    spacing = scans_per_sample(rate_hz)
    traj = trajectory or demo_trajectory(heading_deg)
    record = simulate(traj, ImuModel(), duration_s=duration_s + lead_s + 0.5, rate_hz=rate_hz,
                      seed=seed)
    with PlcClient(*address) as modbus, ArmControllerClient(modbus) as c:
        st = c.move_tool_angles(START_TIP_MM, 0.0, 0.0, wait=True)
        _check("MoveToolAngles to the start pose", st.error_id)
        _check("ImuSelectFilter", c.imu_select_filter("madgwick_marg", 0.0))
        _check("ImuSetPeriod", c.imu_set_period(record.period_s))
        _check("ImuReset", c.imu_reset(tuple(float(v) for v in record.quat_true[0])))
        lead = int(round(lead_s / record.period_s))
        rig.play(record, 1, spacing)
        rig.wait_samples(lead)
        rig.start_recording()
        st = c.follow_imu(flange_fixed=flange_fixed, heading_deg=heading_deg,
                          max_jerk_dps3=max_jerk_dps3)
        if st.error_id != ERR_OK:
            rig.pause()
            raise CommandRejected("FollowImu", st.error_id)
        rig.wait_samples(len(record) - 2, timeout_s=10.0 * duration_s + 60.0)
        rows = rig.take_rows()
        rig.pause()
        c.follow_imu_stop()
    # the rows from the scan the follow started in (its first step is the next sample)
    started = next((i for i, r in enumerate(rows) if r.sample >= lead), 0)
    return analyse(rows[started:], record, heading_deg, flange_fixed)


def per_second(run: FollowRun) -> list[int]:
    """Row indices of the recorded scans at each whole second."""
    return list(range(0, len(run.t), int(round(1.0 / SCAN_S))))


def settled(run: FollowRun, after_s: float = 2.0) -> npt.NDArray[np.bool_]:
    return np.asarray(run.t >= after_s)


def print_report(run: FollowRun, out: TextIO) -> None:
    mode = "flange-fixed" if run.flange_fixed else "tip-fixed"
    out.write(f"FollowImu, {mode}, heading {run.heading_deg:g} deg, IMU at "
              f"{run.rate_hz:g} Hz; hand = ground truth, "
              "arm = FK of the joint outputs (base frame)\n")
    held = "flange" if run.flange_fixed else "tip"
    out.write(f"  t s   hand tool direction    arm tool direction   error  {held} drift"
              "   pitch hand/arm   roll hand/arm\n")
    out.write("                                                      deg      mm"
              "          deg            deg\n")
    for k in per_second(run):
        h, a = run.hand_dir[k], run.arm_dir[k]
        out.write(f"{run.t[k]:5.1f}  {h[0]:6.3f} {h[1]:6.3f} {h[2]:6.3f}  "
                  f"{a[0]:6.3f} {a[1]:6.3f} {a[2]:6.3f}  {run.error_deg[k]:6.2f}  "
                  f"{run.drift_mm[k]:8.3f}  {run.hand_pitch[k]:7.2f} {run.arm_pitch[k]:7.2f}"
                  f"  {run.hand_roll[k]:7.2f} {run.arm_roll[k]:7.2f}\n")
    ok = settled(run)
    out.write(f"after 2 s: direction error mean {run.error_deg[ok].mean():.2f} deg, "
              f"95 % {np.percentile(run.error_deg[ok], 95):.2f} deg, max "
              f"{run.error_deg[ok].max():.2f} deg; held point drift max "
              f"{run.drift_mm[ok].max():.3f} mm (whole run {run.drift_mm.max():.3f} mm)\n")


def imu_rate(text: str) -> float:
    """An IMU rate the 10 ms scan can write: 100 Hz divided by a whole number."""
    value = argtypes.finite(text)
    try:
        scans_per_sample(value)
    except DemoError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return value


def run_from_args(args: argparse.Namespace, out: TextIO | None = None) -> int:
    try:
        with paced_controller() as ctl:
            run = run_follow(ctl.address, ctl.rig, duration_s=args.seconds,
                             heading_deg=args.heading, flange_fixed=args.flange_fixed,
                             seed=args.seed, rate_hz=args.rate)
    except (CommandRejected, DemoError) as exc:
        print(f"demo-imu failed: {exc}", file=sys.stderr)
        return 1
    print_report(run, out or sys.stdout)
    return 0
