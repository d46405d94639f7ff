"""Tip drift of the tip-fixed follow with and without the follower's acceleration limit
(ToolOrientationFollow5Axis's MaxAccDps2), measured side by side in one run (prints figures;
not a test).

The chain is the controller's FollowImu without the Modbus layer, all in compiled ST (st/*.st,
REAL = float32): the simulated hand of ``armbench demo-imu`` (follow_demo.demo_trajectory,
100 Hz, seed 5) -> ImuRawToSample -> MadgwickMarg (started at the true orientation) ->
ToolOrientationFollow5Axis (tip-fixed, dead band 2 deg, 90 deg/s, heading 10 deg) ->
ServoSlewLimiter (150 deg/s, 1000 deg/s^2 per joint, the controller's defaults), one sample
per 10 ms scan and one scan of latency as in the controller. The figures are those of
follow_demo.analyse: the closed-form numpy FK of the limiter's outputs against the hand's
ground truth; drift = the tip's distance from where it was when the follow started.

Run: .venv/bin/python bench/follow_drift.py [--seconds S] [--acc A A ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from armbench.compiler import compile_files
from armbench.follow_demo import SCAN_S, TOOL_MM, ScanRow, analyse, arm_frames, demo_trajectory
from armbench.orientation import quat_dict, run_filter, st_samples
from armbench.plant.arm import DEFAULT_GEOMETRY
from armbench.plant.imu import ImuModel, simulate

ROOT = Path(__file__).resolve().parent.parent
HEADING_DEG = 10.0
START_JOINTS = [0.0, 75.0, 95.0, 10.0, 0.0]  # follow_demo's start pose: tool horizontal
LEAD = 50  # samples the filter runs before the follow starts (0.5 s)


def run(module: object, quats: np.ndarray, record: object, acc: float, scans: int,
        flange_fixed: bool) -> tuple[float, float, float, float, int]:
    geo = {"Arm": DEFAULT_GEOMETRY.as_st(), "ToolMm": TOOL_MM}
    fb = module.new_fb("ToolOrientationFollow5Axis")  # type: ignore[attr-defined]
    slew = module.new_fb("ServoSlewLimiter")  # type: ignore[attr-defined]
    joints = [*START_JOINTS, 0.0]
    slew(Command=joints, Joints=5, MaxVelDeg=[150.0] * 6, MaxAccDeg=[1000.0] * 6,
         CycleTime=SCAN_S, Reset=True)
    slew(Reset=False)
    fb(Enable=True, Start=True, Joints=list(slew.Output), Geometry=geo,
       FlangeFixed=flange_fixed, HeadingDeg=HEADING_DEG,
       MountOffset={"W": 1.0, "X": 0.0, "Y": 0.0, "Z": 0.0}, DeadBandDeg=2.0,
       MaxRateDps=90.0, MaxAccDps2=acc, SamplePeriodS=SCAN_S)
    fb(Start=False)
    rows = []
    limited = 0
    for k in range(scans):
        if k > 0:  # the sample filtered at the end of the last scan
            fb(NewSample=True, Orientation=quat_dict(quats[LEAD + k - 1]))
            if fb.Error:
                raise RuntimeError(f"ToolOrientationFollow5Axis error {fb.ErrorId}")
        slew(Command=list(fb.SetJoints))
        limited += int(slew.Limited)
        rows.append(ScanRow(sample=LEAD + k, joints=tuple(slew.Output[:5])))
    r = analyse(rows, record, HEADING_DEG, flange_fixed)  # type: ignore[arg-type]
    ok = r.t >= 2.0
    return (float(r.drift_mm.max()), float(np.percentile(r.drift_mm[ok], 95)),
            float(np.percentile(r.error_deg[ok], 95)), float(r.error_deg[ok].max()), limited)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--acc", type=float, nargs="+", default=[0.0, 100.0, 200.0, 400.0, 1000.0],
                    help="MaxAccDps2 values, deg/s^2 (0 = off, the controller's setting)")
    args = ap.parse_args(argv)
    if not 1.0 <= args.seconds <= 120.0:
        ap.error("--seconds must lie in 1..120")
    if any(not 0.0 <= a <= 1.0e6 for a in args.acc):
        ap.error("--acc values must lie in 0..1e6 deg/s^2")
    module = compile_files(sorted((ROOT / "st").glob("*.st")))
    record = simulate(demo_trajectory(HEADING_DEG), ImuModel(),
                      duration_s=args.seconds + 1.0, rate_hz=100.0, seed=5)
    quats = run_filter(module, "madgwick_marg", st_samples(module, record), SCAN_S,
                       record.quat_true[0]).quats
    scans = int(round(args.seconds / SCAN_S))
    _, _, tip0 = arm_frames(np.array([START_JOINTS]))
    print(f"follow of the demo hand, {args.seconds:g} s, heading {HEADING_DEG:g} deg, "
          f"start tip {np.round(tip0[0], 2)} mm; dead band 2 deg, rate 90 deg/s; "
          "servo slew 150 deg/s, 1000 deg/s^2")
    print("mode         MaxAccDps2  drift max  drift p95  error p95  error max  "
          "scans slew-limited")
    print("             deg/s^2     mm         mm (>2 s)  deg (>2 s) deg (>2 s)")
    for flange in (False, True):
        for acc in args.acc:
            d_max, d95, e95, e_max, lim = run(module, quats, record, acc, scans, flange)
            mode = "flange-fixed" if flange else "tip-fixed"
            print(f"{mode:12s} {acc:10g}  {d_max:9.3f}  {d95:9.3f}  {e95:9.2f}  {e_max:9.2f}"
                  f"  {lim:6d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
