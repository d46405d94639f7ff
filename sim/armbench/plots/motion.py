"""Figures of docs/motion.md: the motion blocks of st/ run scan by scan through the bench.

Compiles st/*.st, runs MotionJointMove, MotionLinear and MotionJog with a 10 ms scan on one
MotionGroup and plots what they wrote into it; for the jerk-limited comparison, runs
MotionJointMove (trapezoid, quintic) and MotionJerkGenerator on one joint with 1 ms scans:

    python -m armbench.plots.motion            # docs/figures/motion-*.png, see FIGURES
    python -m armbench.plots.motion --out DIR

Part of the plots package, the only one that imports matplotlib.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from armbench.plant import arm
from armbench.plots.cli import figure_target

DT = 0.01  # s, the controller's task period
GEO = arm.DEFAULT_GEOMETRY.as_st()
JOINT_NAMES = ("Base", "Shoulder", "Elbow")
PROFILE_NAMES = ("0 constant speed", "1 synchronised", "2 trapezoid", "3 quintic")
METHOD_NAMES = ("0 Bresenham (seed)", "1 + seed compensation", "2 ours (trapezoid on s)")
# The moves shown (also used by docs/labs/lab6-motion.md).
JOINT_START = (10.0, 40.0, 120.0)
JOINT_TARGET = (-50.0, 75.0, 100.0)
LINE_START = (180.0, -40.0, 150.0)
LINE_END = (150.3, 60.2, 99.7)
LINE_SPEED = 50.0  # mm/s
LINE_ACC = 200.0  # mm/s^2
# The time-optimal jerk-limited profile against the trapezoid and the quintic (also used by
# docs/labs/lab6-motion.md and the teacher's guide): the same limits for all three.
JERK_LIMITS = (60.0, 120.0, 600.0)  # deg/s, deg/s^2, deg/s^3
JERK_MOVE = 90.0  # deg, rest to rest: Lab 6 step 1's move
MOVING_START = (40.0, 100.0)  # deg/s, deg/s^2: the joint is still speeding up
MOVING_MOVE = 60.0  # deg, from that moving start
FINE_DT = 0.001  # s: fine enough that the curves are the profiles, not their scans
JERK_COLOURS = ("tab:orange", "tab:green", "tab:blue")


def new_group(position: Sequence[float], lower: float = -170.0, upper: float = 170.0,
              max_vel: float = 120.0, max_acc: float = 400.0) -> dict[str, Any]:
    """A MotionGroup value for joints 1..3 with the same limits on every joint."""
    pos = [float(np.float32(p)) for p in position] + [0.0] * (6 - len(position))
    return {"Joints": 3, "Position": pos, "Velocity": [0.0] * 6, "Acceleration": [0.0] * 6,
            "Limits": {"LowerDeg": [lower] * 6, "UpperDeg": [upper] * 6,
                       "MaxVelDeg": [max_vel] * 6, "MaxAccDeg": [max_acc] * 6},
            "Owner": 0, "NextOwnerId": 0, "CartesianValid": False,
            "CartesianPos": [0.0, 0.0, 0.0], "PathParameter": 0.0}


@dataclass
class Run:
    """One group driven by blocks scan by scan; setpoints recorded after every scan."""

    group: dict[str, Any]
    q: list[list[float]] = field(default_factory=list)
    qd: list[list[float]] = field(default_factory=list)
    qdd: list[list[float]] = field(default_factory=list)
    cart: list[list[float]] = field(default_factory=list)

    def scan(self, fb: Any, **inputs: Any) -> Any:
        fb(Group=self.group, **inputs)
        self.group = fb.Group
        n = self.group["Joints"]
        self.q.append(list(self.group["Position"][:n]))
        self.qd.append(list(self.group["Velocity"][:n]))
        self.qdd.append(list(self.group["Acceleration"][:n]))
        self.cart.append(list(self.group["CartesianPos"]))
        return fb

    def until_done(self, fb: Any, max_scans: int = 5000, **inputs: Any) -> int:
        for k in range(1, max_scans + 1):
            self.scan(fb, **inputs)
            if not fb.Busy:
                return k
        raise RuntimeError(f"{type(fb).__name__} still busy after {max_scans} scans")

    def array(self, name: str) -> NDArray[np.float64]:
        return np.array(getattr(self, name), dtype=np.float64)


def joint_move(module: Any, profile: int, start: Sequence[float] = JOINT_START,
               target: Sequence[float] = JOINT_TARGET) -> Run:
    run = Run(new_group(start))
    fb = module.new_fb("MotionJointMove")
    run.until_done(fb, Execute=True, Target=list(target) + [0.0] * 3, Profile=profile,
                   Velocity=60.0, Acceleration=150.0, Jerk=2000.0, CycleTime=DT)
    return run


def line_fineness(start: tuple[float, float, float] = LINE_START,
                  end: tuple[float, float, float] = LINE_END, speed: float = LINE_SPEED) -> float:
    """Fineness that makes one Bresenham iteration last one scan (Ts = dt)."""
    p0 = arm.forward(*arm.inverse(*start))
    dv = np.array(end) - p0
    return float(np.linalg.norm(dv) / (np.max(np.abs(dv)) * speed * DT))


def line_move(module: Any, method: int, fineness: float | None = None) -> Run:
    run = Run(new_group(arm.inverse(*LINE_START)))
    fb = module.new_fb("MotionLinear")
    run.until_done(fb, Execute=True, Target=list(LINE_END), Velocity=LINE_SPEED,
                   Acceleration=LINE_ACC, LineMethod=method,
                   Fineness=line_fineness() if fineness is None else fineness,
                   ElbowUp=True, Geometry=GEO, CycleTime=DT)
    return run


def path_speed(run: Run) -> NDArray[np.float64]:
    """Speed along the line's direction per scan, mm/s (first sample: from the start)."""
    p0 = arm.forward(*arm.inverse(*LINE_START))
    pts = np.vstack([p0, run.array("cart")])
    unit = (np.array(LINE_END) - p0) / np.linalg.norm(np.array(LINE_END) - p0)
    return np.asarray(np.diff(pts, axis=0) @ unit / DT, dtype=np.float64)


def joint_profiles_figure(module: Any, out: Path) -> Path:
    fig = Figure(figsize=(13.0, 8.0))
    axes = fig.subplots(3, 4, sharex="col")
    for col, name in enumerate(PROFILE_NAMES):
        run = joint_move(module, col)
        t = DT * np.arange(len(run.q) + 1)
        series = (np.vstack([JOINT_START, run.array("q")]),
                  np.vstack([np.zeros(3), run.array("qd")]),
                  np.vstack([np.zeros(3), run.array("qdd")]))
        for row, (data, unit) in enumerate(zip(series, ("deg", "deg/s", "deg/s²"),
                                               strict=True)):
            ax = axes[row, col]
            for j, joint in enumerate(JOINT_NAMES):
                ax.plot(t, data[:, j], label=joint)
            ax.grid(True, color="0.9")
            if col == 0:
                ax.set_ylabel(("position", "velocity", "acceleration")[row] + f", {unit}")
        axes[0, col].set_title(f"profile {name}", fontsize=10)
        axes[2, col].set_xlabel("time, s")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"MotionJointMove {JOINT_START} → {JOINT_TARGET} deg, Velocity 60 deg/s, "
                 "Acceleration 150 deg/s² (profiles 2, 3; 0 and 1 ramp at the limit "
                 "400 deg/s²), Jerk 2000 deg/s³, 10 ms scans", fontsize=10)
    path = out / "motion-joint-profiles.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


def line_startup_figure(module: Any, out: Path) -> Path:
    fig = Figure(figsize=(11.0, 7.0))
    top, bottom = fig.subplots(2, 1, sharex=True)
    for method, name in enumerate(METHOD_NAMES):
        run = line_move(module, method)
        t = DT * np.arange(1, len(run.q) + 1)
        speed = path_speed(run)
        q = np.vstack([arm.inverse(*LINE_START), run.array("q")])
        joint_speed = np.max(np.abs(np.diff(q, axis=0)), axis=1) / DT
        top.step(t, speed, where="post", label=name)
        bottom.step(t, joint_speed, where="post", label=name)
    top.set_ylabel("tool speed along the line, mm/s")
    bottom.set_ylabel("fastest joint, deg/s")
    bottom.set_xlabel("time, s")
    for ax in (top, bottom):
        ax.grid(True, color="0.9")
        ax.legend(fontsize=9)
    top.set_title(f"MotionLinear {LINE_START} → {LINE_END} mm at {LINE_SPEED} mm/s, one grid "
                  f"step per 10 ms scan (Fineness {line_fineness():.2f}/mm); ours with "
                  f"{LINE_ACC} mm/s²", fontsize=10)
    path = out / "motion-line-startup.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


def line_path_figure(module: Any, out: Path) -> Path:
    """A coarse grid (0.25 steps/mm) so that the staircase shows; deviation per method."""
    fig = Figure(figsize=(12.0, 5.0))
    left, right = fig.subplots(1, 2)
    p0 = arm.forward(*arm.inverse(*LINE_START))
    p1 = np.array(LINE_END)
    dv = p1 - p0
    fineness = 0.25
    for method, name in ((0, METHOD_NAMES[0]), (2, METHOD_NAMES[2])):
        run = line_move(module, method, fineness=fineness)
        pts = np.vstack([p0, run.array("cart")])
        left.plot(pts[:, 0], pts[:, 1], marker="." if method == 0 else None,
                  drawstyle="default", label=name)
        major = int(np.argmax(np.abs(dv)))
        m = (pts[:, major] - p0[major]) / dv[major]
        per_axis = np.max(np.abs(pts - (p0 + np.outer(m, dv))), axis=1)
        progress = np.linspace(0.0, 1.0, len(per_axis))
        right.plot(progress, per_axis * fineness, label=name)
    left.plot([p0[0], p1[0]], [p0[1], p1[1]], color="black", lw=0.8, linestyle=":",
              label="the line")
    left.set_xlabel("x, mm")
    left.set_ylabel("y, mm")
    left.set_aspect("equal")
    left.legend(fontsize=8)
    left.set_title(f"tool path seen from above, Fineness {fineness} steps/mm", fontsize=10)
    right.axhline(0.5, color="grey", linestyle="--", label="half a grid step")
    right.set_xlabel("progress along the move")
    right.set_ylabel("largest per-axis deviation, grid steps")
    right.set_title("distance from the line at the same major-axis coordinate", fontsize=10)
    right.legend(fontsize=8)
    for ax in (left, right):
        ax.grid(True, color="0.9")
    path = out / "motion-line-path.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


def blend_figure(module: Any, out: Path) -> Path:
    fig = Figure(figsize=(11.0, 4.5))
    axes = fig.subplots(1, 2, sharey=True)
    cases = (((-30.0, 90.0, 90.0), "further on: continues from its velocity"),
             ((60.0, 10.0, 140.0), "reversed: brakes at the limit, then goes"))
    for ax, (second, title) in zip(axes, cases, strict=True):
        run = Run(new_group(JOINT_START))
        first_fb = module.new_fb("MotionJointMove")
        second_fb = module.new_fb("MotionJointMove")
        common: dict[str, Any] = {"Execute": True, "Velocity": 80.0, "Acceleration": 200.0,
                                   "Jerk": 2000.0, "CycleTime": DT}
        for _ in range(35):
            run.scan(first_fb, Target=list(JOINT_TARGET) + [0.0] * 3, Profile=2, **common)
        run.until_done(second_fb, Target=list(second) + [0.0] * 3, Profile=2, **common)
        t = DT * np.arange(len(run.q) + 1)
        qd = np.vstack([np.zeros(3), run.array("qd")])
        for j, joint in enumerate(JOINT_NAMES):
            ax.plot(t, qd[:, j], label=joint)
        ax.axvline(35 * DT, color="grey", linestyle=":", label="second Execute")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("time, s")
        ax.grid(True, color="0.9")
    axes[0].set_ylabel("joint velocity, deg/s")
    axes[0].legend(fontsize=8)
    path = out / "motion-blend.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


def jog_figure(module: Any, out: Path) -> Path:
    run = Run(new_group(arm.inverse(*LINE_START), lower=-360.0, upper=360.0, max_vel=500.0))
    fb = module.new_fb("MotionJog")
    limit = []
    inputs = {"MaxSpeed": 60.0, "Acceleration": 300.0, "ElbowUp": True, "Geometry": GEO,
              "CycleTime": DT}
    for k in range(260):
        run.scan(fb, Enable=k < 240, Command=[1.0, 0.0, 0.0], **inputs)
        limit.append(bool(fb.AtLimit))
    p0 = arm.forward(*arm.inverse(*LINE_START))
    pts = np.vstack([p0, run.array("cart")])
    t = DT * np.arange(len(pts))
    speed = np.linalg.norm(np.diff(pts, axis=0), axis=1) / DT
    cp = [arm.shoulder_distance(*p) for p in pts]
    fig = Figure(figsize=(10.0, 5.5))
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(t[1:], speed, label="tool speed, mm/s")
    top.fill_between(t[1:], 0, 65, where=limit, color="tab:red", alpha=0.15,
                     label="AtLimit")
    top.set_ylabel("mm/s")
    top.legend(fontsize=8)
    bottom.plot(t, cp, label="distance from the shoulder axis (Cp), mm")
    bottom.axhline(arm.reach_limits()[1], color="grey", linestyle="--",
                   label="reach shell a3 + a4")
    bottom.set_xlabel("time, s")
    bottom.set_ylabel("mm")
    bottom.legend(fontsize=8)
    for ax in (top, bottom):
        ax.grid(True, color="0.9")
    top.set_title("MotionJog +x at 60 mm/s, 300 mm/s² (joint limits opened): it brakes "
                  "before the reach shell", fontsize=10)
    path = out / "motion-jog.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


@dataclass(frozen=True)
class ProfileTrace:
    """One joint's setpoints after every scan of one block; index 0 is the start state."""

    name: str
    duration: float  # s, the block's own plan (its Duration output)
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]
    qddd: NDArray[np.float64]  # the jerk over the scan ending at t (index 0: 0)


def _one_joint_group(v0: float, a0: float, limits: tuple[float, float, float]) -> dict[str, Any]:
    group = new_group([0.0], max_vel=limits[0], max_acc=limits[1])
    group["Joints"] = 1
    group["Velocity"][0] = v0
    group["Acceleration"][0] = a0
    return group


def compare_profiles(module: Any, dist: float, v0: float = 0.0, a0: float = 0.0,
                     limits: tuple[float, float, float] = JERK_LIMITS, dt: float = FINE_DT,
                     tail: float = 0.15) -> list[ProfileTrace]:
    """The same move of one joint from position 0 with velocity `v0` and acceleration `a0` to
    rest at `dist`, under the same limits (v, a, j): MotionJointMove's trapezoid (profile 2:
    v and a; it starts from v0 and ignores a0) and quintic (profile 3: v, a and j; from v0,
    stretched until it fits), and MotionJerkGenerator's time-optimal jerk-limited profile
    (from v0 and a0), each run scan by scan with a `dt` scan for the longest duration plus
    `tail`. The joint moves have no jerk output: theirs is the change of their acceleration
    over a scan (a step of acceleration shows as a spike of its size over dt)."""
    vmax, amax, jmax = limits
    move_inputs: dict[str, Any] = {"Execute": True, "Target": [dist] + [0.0] * 5,
                                   "Velocity": vmax, "Acceleration": amax, "Jerk": jmax,
                                   "CycleTime": dt}
    moves = []
    for profile, name in ((2, "trapezoid"), (3, "quintic")):
        run = Run(_one_joint_group(v0, a0, limits))
        run.q.append([0.0])
        run.qd.append([v0])
        run.qdd.append([a0])
        fb = run.scan(module.new_fb("MotionJointMove"), Profile=profile, **move_inputs)
        if fb.Error:
            raise RuntimeError(f"MotionJointMove profile {profile} refused the move: ErrorId "
                               f"{fb.ErrorId}")
        moves.append((run, fb, profile, name, float(fb.Duration)))
    gen = module.new_fb("MotionJerkGenerator")
    lim = {"MaxVel": vmax, "MaxAcc": amax, "MaxJerk": jmax}
    zero = [0.0] * 6
    gen_inputs: dict[str, Any] = {
        "Enable": True, "CycleTime": dt, "Joints": 1, "VelocityMode": False, "Sync": 0,
        "TargetPos": [dist] + zero[1:], "TargetVel": zero, "TargetAcc": zero,
        "Limits": [lim] * 6, "StartPos": zero, "StartVel": [v0] + zero[1:],
        "StartAcc": [a0] + zero[1:]}
    gen(**gen_inputs)
    if gen.Error:
        raise RuntimeError(f"MotionJerkGenerator refused the move: ErrorId {gen.ErrorId}")
    durations = [m[-1] for m in moves] + [float(gen.Duration)]
    scans = int(np.ceil((max(durations) + tail) / dt))
    t = np.asarray(dt * np.arange(scans + 1), dtype=np.float64)

    traces = []
    for run, fb, profile, name, duration in moves:
        for _ in range(scans - 1):
            run.scan(fb, Profile=profile, **move_inputs)
        qdd = run.array("qdd")[:, 0]
        traces.append(ProfileTrace(name, duration, t, run.array("q")[:, 0],
                                   run.array("qd")[:, 0], qdd,
                                   np.concatenate([[0.0], np.diff(qdd) / dt])))
    rows = [(0.0, v0, a0, 0.0),
            (gen.Position[0], gen.Velocity[0], gen.Acceleration[0], gen.Jerk[0])]
    for _ in range(scans - 1):
        gen(**gen_inputs)
        rows.append((gen.Position[0], gen.Velocity[0], gen.Acceleration[0], gen.Jerk[0]))
    arr = np.array(rows, dtype=np.float64)
    traces.append(ProfileTrace("time-optimal jerk-limited", durations[2], t, arr[:, 0],
                               arr[:, 1], arr[:, 2], arr[:, 3]))
    return traces


def _jerk_comparison_figure(module: Any, dist: float, v0: float, a0: float,
                            title: str) -> Figure:
    vmax, amax, jmax = JERK_LIMITS
    traces = compare_profiles(module, dist, v0, a0)
    best = traces[-1].duration
    labels = (f"trapezoid (v, a): {traces[0].duration:.3f} s "
              f"({traces[0].duration / best:.2f}×)",
              f"quintic (v, a, j): {traces[1].duration:.3f} s "
              f"({traces[1].duration / best:.2f}×)",
              f"time-optimal jerk-limited (v, a, j): {best:.3f} s")
    fig = Figure(figsize=(10.0, 10.0))
    axes = fig.subplots(4, 1, sharex=True)
    names = ("position, deg", "velocity, deg/s", "acceleration, deg/s²", "jerk, deg/s³")
    for trace, label, colour in zip(traces, labels, JERK_COLOURS, strict=True):
        series = (trace.q, trace.qd, trace.qdd, trace.qddd)
        for row, data in enumerate(series):
            # the jerk over a scan belongs to the scan, drawn as a step ending at t
            if row == 3:
                axes[row].step(trace.t[1:], data[1:], where="pre", color=colour, lw=1.2,
                               label=label)
            else:
                axes[row].plot(trace.t, data, color=colour, lw=1.4, label=label)
    for row, limit in ((1, vmax), (2, amax), (3, jmax)):
        for sign in (1.0, -1.0):
            axes[row].axhline(sign * limit, color="grey", lw=0.8, linestyle="--")
    axes[0].axhline(dist, color="grey", lw=0.8, linestyle=":")
    axes[3].set_ylim(-1.6 * jmax, 1.6 * jmax)
    axes[3].text(0.99, 0.04, "a step of acceleration is unbounded jerk: its spike "
                 f"(step / {FINE_DT * 1000:.0f} ms) leaves the scale",
                 transform=axes[3].transAxes, ha="right", va="bottom", fontsize=8,
                 color="0.3")
    for ax, name in zip(axes, names, strict=True):
        ax.set_ylabel(name)
        ax.grid(True, color="0.9")
    axes[0].legend(fontsize=9, loc="lower right")
    axes[3].set_xlabel("time, s (dashed: the limits)")
    axes[0].set_title(title, fontsize=10)
    return fig


def jerk_rest_figure(module: Any, out: Path) -> Path:
    vmax, amax, jmax = JERK_LIMITS
    fig = _jerk_comparison_figure(
        module, JERK_MOVE, 0.0, 0.0,
        f"{JERK_MOVE:g}° from rest to rest with v = {vmax:g} deg/s, a = {amax:g} deg/s², "
        f"j = {jmax:g} deg/s³\n(MotionJointMove profiles 2 and 3, MotionJerkGenerator; "
        f"{FINE_DT * 1000:.0f} ms scans)")
    path = out / "motion-jerk-rest.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


def jerk_moving_figure(module: Any, out: Path) -> Path:
    vmax, amax, jmax = JERK_LIMITS
    v0, a0 = MOVING_START
    fig = _jerk_comparison_figure(
        module, MOVING_MOVE, v0, a0,
        f"{MOVING_MOVE:g}° from a moving start (v0 = {v0:g} deg/s, a0 = {a0:g} deg/s²) to "
        f"rest, same limits (v = {vmax:g}, a = {amax:g}, j = {jmax:g})\n(the trapezoid and "
        "the quintic start from v0 and drop a0: a step of acceleration at t = 0)")
    path = out / "motion-jerk-moving.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    return path


FIGURES: dict[str, Callable[[Any, Path], Path]] = {
    "motion-joint-profiles.png": joint_profiles_figure,
    "motion-line-startup.png": line_startup_figure,
    "motion-line-path.png": line_path_figure,
    "motion-blend.png": blend_figure,
    "motion-jog.png": jog_figure,
    "motion-jerk-rest.png": jerk_rest_figure,
    "motion-jerk-moving.png": jerk_moving_figure,
}


def main(argv: Sequence[str] | None = None) -> int:
    checkout, out = figure_target("armbench.plots.motion", argv)

    from armbench.compiler import compile_files

    module = compile_files(sorted(checkout.st_dir.glob("*.st")))
    for make in FIGURES.values():
        print(f"wrote {make(module, out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
