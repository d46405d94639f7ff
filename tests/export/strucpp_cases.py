"""The value cross-check of STruC++ against the bench: library POUs on many inputs, each as a
:class:`~strucpp_values.ValueProgram`, with an independent reference for its answers.

References (never output of the ST): numpy closed forms and the float64 reference kinematics
``armbench.plant.arm`` (document 002's transform table), the PCA9685 datasheet's formulas,
Python's exact integer ``math.isqrt`` and float64 ``math.atan2``, the Robotics Toolbox (DH
chain: fkine, fkine_all, jacob0), ahrs 0.4.0's Madgwick.updateIMU, Ruckig (jerk-limited
plans). Tolerances are those of the unit tests of the same POUs (tests/unit/). Inputs are
float32 values (REAL) or integers, drawn from seeded generators: every run checks the same
cases.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from strucpp_values import Out, ValueProgram, Values, assign_list, st_lint, st_real

from armbench.plant import arm

GEOMETRY = arm.DEFAULT_GEOMETRY  # 100 / 20 / 120 / 130 mm, ArmGeometry's defaults


@dataclass(frozen=True)
class RefCheck:
    """One comparison with a reference: the worst error found and the bound it must keep."""

    label: str
    worst: float
    bound: float
    unit: str
    failures: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.worst <= self.bound and not self.failures

    def line(self) -> str:
        status = "ok" if self.ok else "FAILED"
        return f"{self.label}: worst {self.worst:.3g} {self.unit} (bound {self.bound:g}) {status}"


@dataclass(frozen=True)
class ValueCase:
    """A POU (or a family) under test: its program, the reference, and per REAL output its
    natural scale (the arm's reach, half a turn, ...): a difference between the compilers is
    counted in ulps at the larger of the two values and that scale, so that an output
    passing through zero is not judged by the ulps of its smallest values."""

    title: str
    program: ValueProgram
    reference: Callable[[Values], list[RefCheck]]
    scales: dict[str, float] = field(default_factory=dict)


def f32(x: float) -> float:
    return float(np.float32(x))


def f32s(values: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=np.float32)]


def angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def worse(*values: float) -> float:
    """The largest of ``values``, infinite if one is NaN (Python's max drops a NaN that is
    not first)."""
    return math.inf if any(math.isnan(v) for v in values) else max(values)


# ------------------------------------------------------------------ Kinematics.st
def kinematics_case() -> ValueCase:
    """ForwardKinematic_V1 on random joint angles, InverseKinematik_V1 (elbow up and down) on
    random targets inside the reach shell (1 mm clear of it, where the float64 two-acos
    oracle is well conditioned), the 3-DOF arm of document 002."""
    rng = np.random.default_rng(2002)
    n_fk = 200
    base = f32s(rng.uniform(-180.0, 180.0, n_fk))
    shoulder = f32s(rng.uniform(-90.0, 180.0, n_fk))
    elbow = f32s(rng.uniform(0.0, 360.0, n_fk))
    targets: list[tuple[float, float, float]] = []
    while len(targets) < 150:
        x, y, z = (f32(v) for v in rng.uniform([-270.0, -270.0, -160.0], [270.0, 270.0, 360.0]))
        if math.hypot(x, y) > 1.0 and arm.is_reachable(x, y, z, GEOMETRY, margin=1.0):
            targets.append((x, y, z))
    n_ik = len(targets)
    tx, ty, tz = ([t[i] for t in targets] for i in range(3))
    body = "\n".join([
        assign_list("InB", base), assign_list("InS", shoulder), assign_list("InE", elbow),
        assign_list("TX", tx), assign_list("TY", ty), assign_list("TZ", tz),
        f"""  FOR I := 1 TO {n_fk} DO
    Ang.Base := InB[I];
    Ang.Shoulder := InS[I];
    Ang.Elbow := InE[I];
    Pos := ForwardKinematic_V1(Angles := Ang, Geometry := Geo);
    FkX[I] := Pos.X;
    FkY[I] := Pos.Y;
    FkZ[I] := Pos.Z;
  END_FOR;
  FOR I := 1 TO {n_ik} DO
    Target.X := TX[I];
    Target.Y := TY[I];
    Target.Z := TZ[I];
    Sol := InverseKinematik_V1(Target := Target, Geometry := Geo, ElbowUp := TRUE);
    UpB[I] := Sol.Base;
    UpS[I] := Sol.Shoulder;
    UpE[I] := Sol.Elbow;
    Sol := InverseKinematik_V1(Target := Target, Geometry := Geo, ElbowUp := FALSE);
    DownB[I] := Sol.Base;
    DownS[I] := Sol.Shoulder;
    DownE[I] := Sol.Elbow;
  END_FOR;"""])
    program = ValueProgram(
        "StrucppKinematics",
        tuple(Out(n, "REAL", n_fk) for n in ("FkX", "FkY", "FkZ"))
        + tuple(Out(n, "REAL", n_ik) for n in ("UpB", "UpS", "UpE", "DownB", "DownS", "DownE")),
        f"""    InB : ARRAY[1..{n_fk}] OF REAL;
    InS : ARRAY[1..{n_fk}] OF REAL;
    InE : ARRAY[1..{n_fk}] OF REAL;
    TX : ARRAY[1..{n_ik}] OF REAL;
    TY : ARRAY[1..{n_ik}] OF REAL;
    TZ : ARRAY[1..{n_ik}] OF REAL;
    Geo : ArmGeometry;
    Ang : ArmAngles;
    Pos : Coordinates;
    Target : Coordinates;
    Sol : ArmAngles;
    I : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        want = arm.forward_batch(np.column_stack([base, shoulder, elbow]), GEOMETRY)
        got = np.column_stack([v["FKX"], v["FKY"], v["FKZ"]])
        fk = float(np.linalg.norm(got - want, axis=1).max())
        worst = {True: 0.0, False: 0.0}
        for elbow_up, names in ((True, ("UPB", "UPS", "UPE")), (False, ("DOWNB", "DOWNS",
                                                                        "DOWNE"))):
            for k, (x, y, z) in enumerate(targets):
                ref = arm.inverse(x, y, z, GEOMETRY, elbow_up=elbow_up)
                for name, r in zip(names, ref, strict=True):
                    worst[elbow_up] = worse(worst[elbow_up], angle_diff(v[name][k], r))
        # tests/unit/test_kinematics.py: FK 0.01 mm, IK within 0.01 deg of the oracle
        return [RefCheck("ForwardKinematic_V1 vs float64 FK", fk, 0.01, "mm"),
                RefCheck("InverseKinematik_V1 elbow up vs float64 two-acos", worst[True], 0.01,
                         "deg"),
                RefCheck("InverseKinematik_V1 elbow down vs float64 two-acos", worst[False],
                         0.01, "deg")]

    # coordinates at the arm's reach (a2 + a3 + a4 = 270 mm), angles at half a turn
    scales = {**{n: 270.0 for n in ("FkX", "FkY", "FkZ")},
              **{n: 180.0 for n in ("UpB", "UpS", "UpE", "DownB", "DownS", "DownE")}}
    return ValueCase("ForwardKinematic_V1 / InverseKinematik_V1", program, reference, scales)


def wrap_case() -> ValueCase:
    """WrapDeg180 on every half turn from -5.5 to 5.5 turns and on random angles: its
    REAL_TO_DINT meets exact halves there, which STruC++ rounds away from zero (std::round)
    and MatIEC to even; the function must give the same answer either way."""
    rng = np.random.default_rng(7)
    values = [180.0 * k for k in range(-11, 12)] + [f32(180.0 * k + d) for k in (-3, -1, 1, 3)
                                                     for d in (-1e-4, 1e-4)]
    values += f32s(rng.uniform(-5000.0, 5000.0, 300))
    n = len(values)
    body = "\n".join([assign_list("Angle", values), f"""  FOR I := 1 TO {n} DO
    Wrapped[I] := WrapDeg180(Angle[I]);
  END_FOR;"""])
    program = ValueProgram(
        "StrucppWrap", (Out("Wrapped", "REAL", n),),
        f"""    Angle : ARRAY[1..{n}] OF REAL;
    I : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        worst = 0.0
        failures = []
        for k, a in enumerate(values):
            got = v["WRAPPED"][k]
            if not -180.0 < got <= 180.0:
                failures.append(f"WrapDeg180({a}) = {got} outside (-180, 180]")
            worst = worse(worst, angle_diff(got, a))
        # tests/unit/test_kinematics.py: within 1e-3 deg, half-open range
        return [RefCheck("WrapDeg180 vs the angle itself", worst, 1e-3, "deg",
                         tuple(failures))]

    return ValueCase("WrapDeg180 (half turns)", program, reference, {"Wrapped": 180.0})


# ------------------------------------------------------------------ MG996R.st
def mg996r_case() -> ValueCase:
    """MG996R_AngleToPulse / MG996R_PulseToAngle with the default calibration (1000..2000 us
    for -60..+60 deg) and with a reversed, offset one, over and beyond the range."""
    angles = [-75.0 + 0.375 * k for k in range(401)]          # -75 .. 75 deg
    pulses = [850.0 + 3.25 * k for k in range(401)]            # 850 .. 2150 us
    cals = [(0.0, 1, 1000.0, 2000.0, -60.0, 60.0), (30.0, -1, 900.0, 2100.0, -60.0, 60.0)]
    lines = [assign_list("Angle", angles), assign_list("Pulse", pulses)]
    loops = []
    for c, (offset, direction, pmin, pmax, amin, amax) in enumerate(cals):
        loops.append(f"""  Cal.ZeroOffsetDeg := {st_real(offset)};
  Cal.Direction := {direction};
  Cal.MinPulseUs := {st_real(pmin)};
  Cal.MaxPulseUs := {st_real(pmax)};
  Cal.MinAngleDeg := {st_real(amin)};
  Cal.MaxAngleDeg := {st_real(amax)};
  FOR I := 1 TO {len(angles)} DO
    Fwd := MG996R_AngleToPulse(JointAngleDeg := Angle[I], Calibration := Cal);
    PulseOut[{c * len(angles)} + I] := Fwd.PulseUs;
    ServoOut[{c * len(angles)} + I] := Fwd.ServoAngleDeg;
    ClampOut[{c * len(angles)} + I] := Fwd.Clamped;
  END_FOR;
  FOR I := 1 TO {len(pulses)} DO
    Back := MG996R_PulseToAngle(PulseUs := Pulse[I], Calibration := Cal);
    JointOut[{c * len(pulses)} + I] := Back.JointAngleDeg;
  END_FOR;""")
    na, npul = len(angles) * len(cals), len(pulses) * len(cals)
    program = ValueProgram(
        "StrucppServo",
        (Out("PulseOut", "REAL", na), Out("ServoOut", "REAL", na), Out("ClampOut", "BOOL", na),
         Out("JointOut", "REAL", npul)),
        f"""    Angle : ARRAY[1..{len(angles)}] OF REAL;
    Pulse : ARRAY[1..{len(pulses)}] OF REAL;
    Cal : ServoCalibration;
    Fwd : ServoPulse;
    Back : ServoAngle;
    I : INT;""", "\n".join(lines + loops))

    def reference(v: Values) -> list[RefCheck]:
        worst_pulse = worst_angle = 0.0
        failures = []
        for c, (offset, direction, pmin, pmax, amin, amax) in enumerate(cals):
            for k, a in enumerate(angles):
                servo = direction * (a - offset)
                clamped = not amin <= servo <= amax
                servo = min(max(servo, amin), amax)
                want = pmin + (servo - amin) * (pmax - pmin) / (amax - amin)
                i = c * len(angles) + k
                worst_pulse = worse(worst_pulse, abs(v["PULSEOUT"][i] - want))
                if bool(v["CLAMPOUT"][i]) != clamped:
                    failures.append(f"AngleToPulse({a}) Clamped {v['CLAMPOUT'][i]}")
            for k, p in enumerate(pulses):
                pc = min(max(p, pmin), pmax)
                servo = amin + (pc - pmin) * (amax - amin) / (pmax - pmin)
                want = offset + direction * servo
                worst_angle = worse(worst_angle, abs(v["JOINTOUT"][c * len(pulses) + k] - want))
        # tests/unit/test_mg996r.py: 1e-3 us and 1e-3 deg
        return [RefCheck("MG996R_AngleToPulse vs closed form", worst_pulse, 1e-3, "us",
                         tuple(failures)),
                RefCheck("MG996R_PulseToAngle vs closed form", worst_angle, 1e-3, "deg")]

    return ValueCase("MG996R angle <-> pulse", program, reference,
                     {"PulseOut": 2000.0, "ServoOut": 90.0, "JointOut": 90.0})


# ------------------------------------------------------------------ PCA9685.st
def pca9685_case() -> ValueCase:
    """PCA9685_Prescale over oscillators and frequencies (halves left out: float32 and
    float64 may round them apart), PCA9685_PulseToCounts over pulses and phases."""
    pairs = []
    for osc in (25.0e6, 24.5e6, 26.2e6, 27.0e6):
        for freq in (1.0, 20.0, 24.0, 30.0, 40.0, 50.0, 60.0, 100.0, 200.0, 333.0, 500.0,
                     1000.0, 1500.0, 1526.0, 2000.0):
            ratio = osc / (4096.0 * freq)
            if abs(ratio - math.floor(ratio) - 0.5) > 1e-3:
                pairs.append((f32(osc), f32(freq)))
    tick_us = 122 / 25.0e6 * 1e6
    pulses = []
    for k in range(300):
        p = f32(-10.0 + 70.0 * k)  # -10 .. 20920 us: off, servo range, full on
        if abs(p / tick_us - math.floor(p / tick_us) - 0.5) > 1e-3:
            pulses.append(p)
    phases = [0, 7, 4000, 4095, 4096 + 10]
    np_, nc = len(pairs), len(pulses) * len(phases)
    body = "\n".join([
        assign_list("Osc", [p[0] for p in pairs]), assign_list("Freq", [p[1] for p in pairs]),
        assign_list("Pulse", pulses), assign_list("Phase", phases, str),
        f"""  FOR I := 1 TO {np_} DO
    Pre := PCA9685_Prescale(FrequencyHz := Freq[I], OscillatorHz := Osc[I]);
    PreOut[I] := Pre.Prescale;
    HzOut[I] := Pre.ActualHz;
    PreClamped[I] := Pre.Clamped;
  END_FOR;
  FOR J := 1 TO {len(phases)} DO
    FOR I := 1 TO {len(pulses)} DO
      Cnt := PCA9685_PulseToCounts(PulseUs := Pulse[I], Prescale := 121,
                                   OscillatorHz := 25.0E6, PhaseCounts := Phase[J]);
      OnOut[(J - 1) * {len(pulses)} + I] := Cnt.OnWord;
      OffOut[(J - 1) * {len(pulses)} + I] := Cnt.OffWord;
    END_FOR;
  END_FOR;"""])
    program = ValueProgram(
        "StrucppPwm",
        (Out("PreOut", "BYTE", np_), Out("HzOut", "REAL", np_), Out("PreClamped", "BOOL", np_),
         Out("OnOut", "WORD", nc), Out("OffOut", "WORD", nc)),
        f"""    Osc : ARRAY[1..{np_}] OF REAL;
    Freq : ARRAY[1..{np_}] OF REAL;
    Pulse : ARRAY[1..{len(pulses)}] OF REAL;
    Phase : ARRAY[1..{len(phases)}] OF UINT;
    Pre : PCA9685_PrescaleResult;
    Cnt : PCA9685_Counts;
    I : INT;
    J : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        failures = []
        worst_hz = 0.0
        for k, (osc, freq) in enumerate(pairs):
            raw = math.floor(osc / (4096.0 * freq) + 0.5) - 1
            want = min(max(raw, 3), 255)
            if v["PREOUT"][k] != want or bool(v["PRECLAMPED"][k]) != (want != raw):
                failures.append(f"Prescale({freq} Hz, {osc} Hz) = {v['PREOUT'][k]}, want {want}")
            actual = osc / (4096.0 * (want + 1))
            worst_hz = worse(worst_hz, abs(v["HZOUT"][k] - actual) / actual)
        for j, phase in enumerate(phases):
            for k, p in enumerate(pulses):
                counts = 0 if p <= 0.0 else math.floor(p / tick_us + 0.5)
                if counts <= 0:
                    on, off = 0, 0x1000
                elif counts >= 4096:
                    on, off = 0x1000, 0
                else:
                    on = phase % 4096
                    off = (on + counts) % 4096
                i = j * len(pulses) + k
                if (v["ONOUT"][i], v["OFFOUT"][i]) != (on, off):
                    failures.append(f"PulseToCounts({p} us, phase {phase}) = "
                                    f"{v['ONOUT'][i]}/{v['OFFOUT'][i]}, want {on}/{off}")
        # tests/unit/test_pca9685.py: ActualHz to 1e-6 relative, counts exact
        return [RefCheck("PCA9685_Prescale / PulseToCounts vs datasheet", worst_hz, 1e-6,
                         "relative (ActualHz)", tuple(failures[:10]))]

    return ValueCase("PCA9685 prescale and counts", program, reference)


# ------------------------------------------------------------------ KinematicsFixed.st
def _fixed_targets(rng: np.random.Generator, count: int) -> list[tuple[int, int, int]]:
    """Integer targets (0.01 mm) inside the reach shell, 2 um clear of its bands on both
    sides (the ST's 1 um tolerance), some reached only over the base axis."""
    low, high = arm.reach_limits(GEOMETRY)
    out: list[tuple[int, int, int]] = []
    while len(out) < count:
        radial = rng.uniform(0.0, GEOMETRY.a2 + high)
        z = rng.uniform(GEOMETRY.a1 - high, GEOMETRY.a1 + high)
        base = rng.uniform(-math.pi, math.pi)
        p = (round(radial * math.cos(base) * 100), round(radial * math.sin(base) * 100),
             round(z * 100))
        if p[0] == 0 and p[1] == 0:
            continue
        r = math.hypot(p[0], p[1]) / 100.0
        zp = p[2] / 100.0 - GEOMETRY.a1
        sides = (math.hypot(r - GEOMETRY.a2, zp), math.hypot(-r - GEOMETRY.a2, zp))
        if any(abs(cp - high) < 2e-3 or abs(cp - low) < 2e-3 for cp in sides):
            continue
        if any(low < cp < high for cp in sides):
            out.append(p)
    return out


def fixed_ik_case() -> ValueCase:
    """InverseKinematikFixed (integer-only, lookup-table trig) on integer targets, both elbow
    choices, against float64 at the same integer target."""
    targets = _fixed_targets(np.random.default_rng(2024), 150)
    n = len(targets)
    body = "\n".join([
        assign_list("TX", [t[0] for t in targets], str),
        assign_list("TY", [t[1] for t in targets], str),
        assign_list("TZ", [t[2] for t in targets], str),
        f"""  FOR J := 0 TO 1 DO
    FOR I := 1 TO {n} DO
      Ik(XMm100 := TX[I], YMm100 := TY[I], ZMm100 := TZ[I], ElbowUp := J = 0,
         Geometry := Geo);
      BaseOut[J * {n} + I] := Ik.Angles.BaseDeg100;
      ShoulderOut[J * {n} + I] := Ik.Angles.ShoulderDeg100;
      ElbowOut[J * {n} + I] := Ik.Angles.ElbowDeg100;
      ValidOut[J * {n} + I] := Ik.Valid;
    END_FOR;
  END_FOR;"""])
    program = ValueProgram(
        "StrucppFixedIk",
        (Out("BaseOut", "DINT", 2 * n), Out("ShoulderOut", "DINT", 2 * n),
         Out("ElbowOut", "DINT", 2 * n), Out("ValidOut", "BOOL", 2 * n)),
        f"""    TX : ARRAY[1..{n}] OF DINT;
    TY : ARRAY[1..{n}] OF DINT;
    TZ : ARRAY[1..{n}] OF DINT;
    Geo : ArmGeometryFixed;
    Ik : InverseKinematikFixed;
    I : INT;
    J : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        worst = 0.0
        failures = []
        for j, elbow_up in enumerate((True, False)):
            for k, (x, y, z) in enumerate(targets):
                i = j * n + k
                if not v["VALIDOUT"][i]:
                    failures.append(f"no answer for {(x, y, z)}")
                    continue
                ref = arm.inverse(x / 100.0, y / 100.0, z / 100.0, GEOMETRY, elbow_up)
                got = (v["BASEOUT"][i] / 100.0, v["SHOULDEROUT"][i] / 100.0,
                       v["ELBOWOUT"][i] / 100.0)
                worst = worse(worst, *(angle_diff(g, r) for g, r in zip(got, ref, strict=True)))
        # tests/unit/test_kinematics_fixed.py: the goal, 0.01 deg
        return [RefCheck("InverseKinematikFixed vs float64", worst, 0.01, "deg",
                         tuple(failures[:10]))]

    return ValueCase("InverseKinematikFixed (LUT IK)", program, reference)


def atan2_case() -> ValueCase:
    """Atan2Fixed at every octant and scale, at its extremes (2^61, 2^62, 2^63 - 1 and
    LINT's most negative value): the literals above 2^53 are where STruC++ once went wrong."""
    big = 2**63 - 1
    special = [(0, 0), (0, 5), (0, -5), (5, 0), (-5, 0), (7, 7), (-7, 7), (7, -7), (-7, -7),
               (1, 2**60), (2**60, 1), (-(2**61), 3), (2**61, -(2**61)), (2**61, 2**61),
               (-(2**61), -(2**61)), (2**62, 2**62 - 1), (2**62 - 1, 2**62),
               (big, big), (-big, big), (big, -big), (-big, -big), (big, 0), (0, big),
               (-big, 0), (0, -big), (1, big), (big, 1), (-1, -big), (-(2**63), 1),
               (1, -(2**63)), (-(2**63), -(2**63)), (2**53 + 1, 2**53), (-(2**53) - 1, 3)]
    rng = np.random.default_rng(5)
    pairs = list(special)
    for scale in (10, 10**4, 10**9, 10**15, 2**61, 2**62):
        ys = rng.integers(-scale, scale, 40, dtype=np.int64)
        xs = rng.integers(-scale, scale, 40, dtype=np.int64)
        pairs += [(int(a), int(b)) for a, b in zip(ys, xs, strict=True)]
    n = len(pairs)
    body = "\n".join([
        assign_list("Ys", [p[0] for p in pairs], st_lint),
        assign_list("Xs", [p[1] for p in pairs], st_lint),
        f"""  FOR I := 1 TO {n} DO
    Arc(Y := Ys[I], X := Xs[I]);
    AngleOut[I] := Arc.AngleDeg10k;
  END_FOR;"""])
    program = ValueProgram("StrucppAtan2", (Out("AngleOut", "DINT", n),),
                           f"""    Ys : ARRAY[1..{n}] OF LINT;
    Xs : ARRAY[1..{n}] OF LINT;
    Arc : Atan2Fixed;
    I : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        worst = 0.0
        failures = []
        for k, (y, x) in enumerate(pairs):
            got = v["ANGLEOUT"][k] / 1e4
            if not -180.0 < got <= 180.0:
                failures.append(f"Atan2Fixed({y}, {x}) = {got} deg outside (-180, 180]")
            # the most negative LINT is taken as -(2^63 - 1) (the POU's header)
            ye, xe = max(y, -big), max(x, -big)
            want = math.degrees(math.atan2(ye, xe)) if (ye, xe) != (0, 0) else 0.0
            worst = worse(worst, angle_diff(got, want))
        # tests/unit/test_kinematics_fixed.py: 2.3e-4 deg
        return [RefCheck("Atan2Fixed vs math.atan2", worst, 2.3e-4, "deg",
                         tuple(failures))]

    return ValueCase("Atan2Fixed (incl. 2^61, 2^63 - 1)", program, reference)


def sqrt_case() -> ValueCase:
    """IsqrtFixed (exact floor) and SqrtNormFixed (31-bit mantissa and shift) over LINT."""
    rng = np.random.default_rng(61131)
    values = [0, 1, 2, 3, 4, 15, 16, 17, 2**52, 2**53 + 1, 2**60 - 1, 2**62 - 1, 2**62,
              2**63 - 1, (2**31 - 1) ** 2, (2**31 - 1) ** 2 - 1, 3037000499**2,
              3037000499**2 - 1, -5]
    values += [int(x) for x in rng.integers(0, 2**63 - 1, 120, dtype=np.int64)]
    values += [int(x) for x in rng.integers(0, 2**20, 40, dtype=np.int64)]
    values += [int(r) ** 2 + d for r in rng.integers(1, 3 * 10**9, 20) for d in (-1, 0, 1)]
    n = len(values)
    body = "\n".join([assign_list("Vals", values, st_lint), f"""  FOR I := 1 TO {n} DO
    Isq(Value := Vals[I]);
    RootOut[I] := Isq.Root;
    Norm(Value := Vals[I]);
    MantOut[I] := Norm.Root;
    ShiftOut[I] := Norm.Shift;
  END_FOR;"""])
    program = ValueProgram(
        "StrucppSqrt",
        (Out("RootOut", "LINT", n), Out("MantOut", "LINT", n), Out("ShiftOut", "DINT", n)),
        f"""    Vals : ARRAY[1..{n}] OF LINT;
    Isq : IsqrtFixed;
    Norm : SqrtNormFixed;
    I : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        failures = []
        worst = 0.0
        for k, x in enumerate(values):
            want = math.isqrt(x) if x > 0 else 0
            if v["ROOTOUT"][k] != want:
                failures.append(f"IsqrtFixed({x}) = {v['ROOTOUT'][k]}, want {want}")
            root, shift = int(v["MANTOUT"][k]), int(v["SHIFTOUT"][k])
            if 1 <= x < 2**62:
                scaled = x * 4**shift
                if not (2**30 <= root <= 2**31 and 0 <= shift <= 30):
                    failures.append(f"SqrtNormFixed({x}) = {root}, {shift}: out of range")
                worst = worse(worst, abs(root - math.sqrt(scaled)))
                # exactly: |root - sqrt(scaled)| <= 1
                if not (root - 1) ** 2 <= scaled <= (root + 1) ** 2:
                    failures.append(f"SqrtNormFixed({x}) = {root} * 2^-{shift}")
            elif (root, shift) != (0, 0):
                failures.append(f"SqrtNormFixed({x}) = {root}, {shift}, want 0, 0")
        return [RefCheck("IsqrtFixed vs math.isqrt (exact), SqrtNormFixed within 1", worst,
                         1.0, "mantissa units", tuple(failures[:10]))]

    return ValueCase("IsqrtFixed / SqrtNormFixed", program, reference)


# ------------------------------------------------------------------ KinematicsChain.st
def chain_case() -> ValueCase:
    """The Puma 560 (the Robotics Toolbox's, in mm) as a DH table: ForwardKinematic_Chain,
    ChainFramePoses and ChainJacobian at random joints, InverseKinematik_Chain (damped least
    squares, pose task) from seeds 0.3 rad off."""
    from unit.chain_models import MM_PER_M, chain_of, joints_st, pose_st, puma560

    robot = puma560()
    chain = chain_of(robot, MM_PER_M)
    rng = np.random.default_rng(560)
    n_fk = 30
    qs = [np.array([rng.uniform(-math.pi, math.pi) for _ in range(6)]) for _ in range(n_fk)]
    joints = [[f32(v) for v in joints_st(robot, q, MM_PER_M)] for q in qs]
    n_ik = 8
    qt = [np.array(rng.uniform(-1.2, 1.2, 6)) for _ in range(n_ik)]
    ik_targets = [pose_st(robot.fkine(q).A, MM_PER_M) for q in qt]
    seeds = [[f32(v) for v in joints_st(robot, q + 0.3, MM_PER_M)] for q in qt]
    setup = []
    for i, link in enumerate(chain["Links"], start=1):
        for key in ("A", "AlphaDeg", "D", "ThetaOffsetDeg"):
            setup.append(f"  Chain.Links[{i}].{key} := {st_real(f32(link[key]))};")
        setup.append(f"  Chain.Links[{i}].Prismatic := {'TRUE' if link['Prismatic'] else 'FALSE'};")
    setup += [f"  Chain.Count := {chain['Count']};",
              f"  Chain.Modified := {'TRUE' if chain['Modified'] else 'FALSE'};"]
    flat_q = [x for j in joints for x in j]
    flat_target = [f32(x) for t in ik_targets for row in t for x in row]
    flat_seed = [x for s in seeds for x in s]
    body = "\n".join(setup + [
        assign_list("Qs", flat_q), assign_list("Tgt", flat_target), assign_list("Seeds", flat_seed),
        f"""  FOR K := 1 TO {n_fk} DO
    FOR J := 1 TO 6 DO
      Q[J] := Qs[(K - 1) * 6 + J];
    END_FOR;
    T := ForwardKinematic_Chain(Chain := Chain, Joints := Q);
    Frames := ChainFramePoses(Chain := Chain, Joints := Q);
    Jac := ChainJacobian(Chain := Chain, Joints := Q);
    FOR R := 1 TO 3 DO
      FOR C := 1 TO 3 DO
        RotOut[(K - 1) * 9 + (R - 1) * 3 + C] := T[R, C];
      END_FOR;
      PosOut[(K - 1) * 3 + R] := T[R, 4];
    END_FOR;
    FOR F := 1 TO 6 DO
      FOR R := 1 TO 3 DO
        FrameOut[(K - 1) * 18 + (F - 1) * 3 + R] := Frames[F].Pose[R, 4];
      END_FOR;
    END_FOR;
    FOR R := 1 TO 3 DO
      FOR C := 1 TO 6 DO
        JacLin[(K - 1) * 18 + (R - 1) * 6 + C] := Jac[R, C];
        JacAng[(K - 1) * 18 + (R - 1) * 6 + C] := Jac[R + 3, C];
      END_FOR;
    END_FOR;
  END_FOR;
  FOR K := 1 TO {n_ik} DO
    FOR R := 1 TO 3 DO
      Target.AxisX[R] := Tgt[(K - 1) * 16 + (R - 1) * 4 + 1];
      Target.AxisY[R] := Tgt[(K - 1) * 16 + (R - 1) * 4 + 2];
      Target.AxisZ[R] := Tgt[(K - 1) * 16 + (R - 1) * 4 + 3];
      Target.Origin[R] := Tgt[(K - 1) * 16 + (R - 1) * 4 + 4];
    END_FOR;
    FOR J := 1 TO 6 DO
      Seed[J] := Seeds[(K - 1) * 6 + J];
    END_FOR;
    Ik(Execute := FALSE, Chain := Chain, Target := Target, Seed := Seed);
    Ik(Execute := TRUE, Chain := Chain, Target := Target, Seed := Seed, ItersPerScan := 1000,
       MaxIters := 1000);
    FOR J := 1 TO 6 DO
      IkOut[(K - 1) * 6 + J] := Ik.Joints[J];
    END_FOR;
    IkDone[K] := Ik.Done AND NOT Ik.Error;
    IkIters[K] := Ik.Iterations;
  END_FOR;"""])
    program = ValueProgram(
        "StrucppChain",
        (Out("RotOut", "REAL", n_fk * 9), Out("PosOut", "REAL", n_fk * 3),
         Out("FrameOut", "REAL", n_fk * 18), Out("JacLin", "REAL", n_fk * 18),
         Out("JacAng", "REAL", n_fk * 18), Out("IkOut", "REAL", n_ik * 6),
         Out("IkDone", "BOOL", n_ik), Out("IkIters", "INT", n_ik)),
        f"""    Qs : ARRAY[1..{len(flat_q)}] OF REAL;
    Tgt : ARRAY[1..{len(flat_target)}] OF REAL;
    Seeds : ARRAY[1..{len(flat_seed)}] OF REAL;
    Chain : KinematicChain;
    Q : JointVector;
    Seed : JointVector;
    T : Mat4;
    Target : ChainPose;
    Frames : ChainFrameStack;
    Jac : ChainMat6;
    Ik : InverseKinematik_Chain;
    K : INT;
    J : INT;
    R : INT;
    C : INT;
    F : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        from unit.chain_models import joints_rtb, rotation_angle_deg

        fk_pos = fk_rot = frame_pos = jac = 0.0
        for k, j in enumerate(joints):
            q = joints_rtb(robot, j, MM_PER_M)  # the float32 joints the ST got
            ref = robot.fkine(q).A
            pos = np.array(v["POSOUT"][k * 3:(k + 1) * 3])
            rot = np.array(v["ROTOUT"][k * 9:(k + 1) * 9]).reshape(3, 3)
            fk_pos = worse(fk_pos, float(np.abs(pos - ref[:3, 3] * MM_PER_M).max()))
            fk_rot = worse(fk_rot, float(np.abs(rot - ref[:3, :3]).max()))
            frames = robot.fkine_all(q)
            for f in range(1, 7):
                got_f = np.array(v["FRAMEOUT"][k * 18 + (f - 1) * 3:k * 18 + f * 3])
                frame_pos = worse(frame_pos, float(np.abs(
                    got_f - frames[f].A[:3, 3] * MM_PER_M).max()))
            J = np.vstack([np.array(v["JACLIN"][k * 18:(k + 1) * 18]).reshape(3, 6) / MM_PER_M,
                           np.array(v["JACANG"][k * 18:(k + 1) * 18]).reshape(3, 6)])
            # (rows 1..3 from mm per rad to the toolbox's m per rad: all joints revolute)
            jac = worse(jac, float(np.abs(J - robot.jacob0(q)).max()))
        res_mm = res_deg = 0.0
        failures = []
        for k in range(n_ik):
            if not v["IKDONE"][k]:
                failures.append(f"InverseKinematik_Chain target {k + 1} not solved")
                continue
            q = joints_rtb(robot, v["IKOUT"][k * 6:(k + 1) * 6], MM_PER_M)
            T = robot.fkine(q).A
            want = np.array(ik_targets[k])
            res_mm = worse(res_mm, float(np.linalg.norm(T[:3, 3] * MM_PER_M - want[:3, 3])))
            res_deg = worse(res_deg, rotation_angle_deg(T[:3, :3], want[:3, :3]))
        # tests/unit/test_chain_fk.py and test_chain_ik.py
        return [RefCheck("ForwardKinematic_Chain position vs rtb fkine", fk_pos, 1e-3, "mm"),
                RefCheck("ForwardKinematic_Chain rotation vs rtb fkine", fk_rot, 1e-5, ""),
                RefCheck("ChainFramePoses origins vs rtb fkine_all", frame_pos, 1e-3, "mm"),
                RefCheck("ChainJacobian vs rtb jacob0", jac, 1e-5, "m/rad, rad/rad"),
                RefCheck("InverseKinematik_Chain residual (rtb fkine)", res_mm, 0.01, "mm",
                         tuple(failures)),
                RefCheck("InverseKinematik_Chain rotation residual", res_deg, 1e-3, "deg")]

    # the Puma's reach is about 900 mm, its angles and rotations of order 1 and 180 deg
    scales = {"RotOut": 1.0, "PosOut": 1000.0, "FrameOut": 1000.0, "JacLin": 1000.0,
              "JacAng": 1.0, "IkOut": 180.0}
    return ValueCase("DH chain (Puma 560): FK, frames, Jacobian, DLS IK", program, reference,
                     scales)


# ------------------------------------------------------------------ OrientationFilters.st
MADGWICK_BETA = 0.033
MADGWICK_DT = 0.01


def _imu_samples(count: int) -> tuple[list[list[float]], list[list[float]]]:
    """A hand turning about all three axes: gyro (deg/s, with noise and bias) and the
    accelerometer's gravity direction in the body frame (g, with noise), float32."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4004)
    rot = Rotation.identity()
    gyro, accel = [], []
    for k in range(count):
        t = k * MADGWICK_DT
        rate = np.array([40.0 * math.sin(1.3 * t), 25.0 * math.cos(0.7 * t) + 5.0,
                         30.0 * math.sin(0.5 * t + 1.0)])
        rot = rot * Rotation.from_rotvec(np.radians(rate) * MADGWICK_DT)
        g_body = rot.inv().apply([0.0, 0.0, 1.0])
        gyro.append(f32s(rate + rng.normal(0.0, 0.2, 3) + [0.3, -0.2, 0.1]))
        accel.append(f32s(g_body + rng.normal(0.0, 0.01, 3)))
    return gyro, accel


def madgwick_case() -> ValueCase:
    """MadgwickImu over 300 samples from the identity (Beta 0.033, 10 ms), every output
    quaternion, against ahrs 0.4.0's Madgwick.updateIMU on the same samples."""
    gyro, accel = _imu_samples(300)
    n = len(gyro)
    body = "\n".join([
        assign_list("Gx", [g[0] for g in gyro]), assign_list("Gy", [g[1] for g in gyro]),
        assign_list("Gz", [g[2] for g in gyro]), assign_list("Ax", [a[0] for a in accel]),
        assign_list("Ay", [a[1] for a in accel]), assign_list("Az", [a[2] for a in accel]),
        f"""  Filt(Reset := TRUE, InitialQuat := Start, InitFromSensors := FALSE,
       Beta := {st_real(f32(MADGWICK_BETA))}, SamplePeriodS := {st_real(f32(MADGWICK_DT))});
  FOR K := 1 TO {n} DO
    Smp.Gyro.X := Gx[K];
    Smp.Gyro.Y := Gy[K];
    Smp.Gyro.Z := Gz[K];
    Smp.Accel.X := Ax[K];
    Smp.Accel.Y := Ay[K];
    Smp.Accel.Z := Az[K];
    Filt(Reset := FALSE, Sample := Smp);
    QW[K] := Filt.Orientation.W;
    QX[K] := Filt.Orientation.X;
    QY[K] := Filt.Orientation.Y;
    QZ[K] := Filt.Orientation.Z;
    Codes[K] := Filt.ErrorId;
  END_FOR;"""])
    program = ValueProgram(
        "StrucppMadgwick",
        (*(Out(c, "REAL", n) for c in ("QW", "QX", "QY", "QZ")), Out("Codes", "INT", n)),
        "\n".join(f"    {c} : ARRAY[1..{n}] OF REAL;" for c in ("Gx", "Gy", "Gz", "Ax", "Ay",
                                                                 "Az"))
        + """
    Filt : MadgwickImu;
    Start : Quaternion;
    Smp : ImuSample;
    K : INT;""", body)

    def reference(v: Values) -> list[RefCheck]:
        from ahrs.filters import Madgwick

        mw = Madgwick(Dt=f32(MADGWICK_DT), gain=f32(MADGWICK_BETA))
        q = np.array([1.0, 0.0, 0.0, 0.0])
        worst = 0.0
        for k in range(n):
            q = mw.updateIMU(q, np.radians(np.array(gyro[k])), np.array(accel[k]))
            got = np.array([v[c][k] for c in ("QW", "QX", "QY", "QZ")])
            worst = worse(worst, float(np.abs(got - q).max()))
        failures = tuple(f"sample {k + 1} rejected ({c})" for k, c in enumerate(v["CODES"]) if c)
        # tests/unit/test_orientation_filters.py: 2e-6 per component
        return [RefCheck("MadgwickImu vs ahrs updateIMU", worst, 2e-6, "per component",
                         failures)]

    return ValueCase("MadgwickImu over 300 samples", program, reference,
                     {c: 1.0 for c in ("QW", "QX", "QY", "QZ")})


# ------------------------------------------------------------------ MotionJerk*.st
def _single_plan(k: int, c: Any) -> str:
    """ST planning one axis, ``c`` (a jerk_support.AxisCase), as plan ``k`` of the program:
    into Profs[k], Durations[k], Codes[k]."""
    return f"""  CurP[1] := {st_real(c.p0)};
  CurV[1] := {st_real(c.v0)};
  CurA[1] := {st_real(c.a0)};
  TgtP[1] := {st_real(c.pf)};
  TgtV[1] := {st_real(c.vf)};
  TgtA[1] := {st_real(c.af)};
  Lim[1].MaxVel := {st_real(c.vmax)};
  Lim[1].MaxAcc := {st_real(c.amax)};
  Lim[1].MaxJerk := {st_real(c.jmax)};
  Lim[1].SeparateMin := {"TRUE" if c.vmin is not None or c.amin is not None else "FALSE"};
  Lim[1].MinVel := {st_real(c.v_lo)};
  Lim[1].MinAcc := {st_real(c.a_lo)};
  One(Joints := 1, VelocityMode := FALSE, Sync := 0, CurrentPos := CurP, CurrentVel := CurV,
      CurrentAcc := CurA, TargetPos := TgtP, TargetVel := TgtV, TargetAcc := TgtA,
      Limits := Lim);
  Profs[{k}] := One.Profiles[1];
  Durations[{k}] := One.Duration;
  Codes[{k}] := One.ErrorId;"""


def jerk_case() -> ValueCase:
    """The jerk-limited family: MotionJerkPlanner on three axes together (moving start,
    target velocity), the positions on MotionJerkAt at three times, a velocity-interface jog,
    and MotionJerkGenerator for 60 cycles through a target change (the program of
    tests/unit/test_motion_jerk_matiec.py); then single-axis plans of every case family of
    tests/unit/jerk_support.py (rest, moving, target velocity, short, long, degenerate,
    outside the limits, separate minimum limits), sampled along their duration; against
    Ruckig."""
    import random

    from unit.jerk_support import (
        CROSS_AXES,
        CROSS_DECLS,
        CROSS_JOG,
        CROSS_TIMES,
        FAMILIES,
        CrossOutputs,
        axis_case,
        cross_body,
        cross_ruckig_generator,
    )

    rng = random.Random(61131)
    singles = [axis_case(rng, family) for family in FAMILIES for _ in range(2)]
    fractions = (0.25, 0.5, 0.75, 1.0, 1.5)

    axes, jog, times = CROSS_AXES, CROSS_JOG, CROSS_TIMES
    outputs = CrossOutputs("Lreals[1]", "Ints[1]", lambda i, k: f"Samples[{i * 3 + k}]",
                           "Lreals[2]", "Lreals[3]", "Lreals[4]", "Lreals[5]", "Lreals[6]",
                           "Ints[2]")
    body = cross_body(st_real, outputs) + "\n" + "\n".join(
        _single_plan(k, c) for k, c in enumerate(singles, 1)) + f"""
  FOR K := 1 TO {len(singles)} DO
    FOR J := 1 TO {len(fractions)} DO
      Pt := MotionJerkAt(Prof := Profs[K], TimeS := Durations[K] * Fracs[J]);
      Along[(K - 1) * {len(fractions)} + J] := Pt.Pos;
    END_FOR;
  END_FOR;"""
    body = assign_list("Fracs", list(fractions)) + "\n" + body
    program = ValueProgram(
        "StrucppJerk",
        (Out("Lreals", "LREAL", 6), Out("Samples", "LREAL", 9), Out("Ints", "INT", 2),
         Out("Durations", "LREAL", len(singles)), Out("Codes", "INT", len(singles)),
         Out("Along", "LREAL", len(singles) * len(fractions))),
        f"""    Profs : ARRAY[1..{len(singles)}] OF MotionJerkProfile;
    Fracs : ARRAY[1..{len(fractions)}] OF LREAL;
    One : MotionJerkPlanner;
    J : INT;
    TgtA : MotionJerkVector;
{CROSS_DECLS}""", body)

    def reference(v: Values) -> list[RefCheck]:
        from unit.jerk_support import expected_error_ids, pos_tolerance, ruckig_plan

        failures = []
        if v["INTS"] != [0, 2]:
            failures.append(f"ErrorId, plans = {v['INTS']}, want [0, 2]")
        ref = ruckig_plan(axes)
        dur = abs(v["LREALS"][0] - ref.duration) / ref.duration
        pos = 0.0
        for i, t in enumerate(times):
            p_ref = ref.at(t)[0]
            pos = worse(pos, *(abs(v["SAMPLES"][i * 3 + k] - p_ref[k]) for k in range(3)))
        jog_ref = ruckig_plan((jog,), interface="Velocity")
        jog_dur = abs(v["LREALS"][1] - jog_ref.duration) / jog_ref.duration
        pos = worse(pos, abs(v["LREALS"][2] - jog_ref.at(jog_ref.duration)[0][0]))
        gen = worse(*(abs(a - b) for a, b in zip(v["LREALS"][3:6], cross_ruckig_generator(),
                                                  strict=True)))
        single_dur = single_pos = 0.0
        for k, case in enumerate(singles):
            one = ruckig_plan((case,))
            got = v["DURATIONS"][k]
            if not one.ok:
                if v["CODES"][k] not in expected_error_ids(one):
                    failures.append(f"plan {k + 1}: Ruckig {one.result}, ErrorId "
                                    f"{v['CODES'][k]}")
                continue
            if v["CODES"][k] != 0:
                failures.append(f"plan {k + 1}: ErrorId {v['CODES'][k]}, Ruckig planned")
                continue
            single_dur = worse(single_dur, abs(got - one.duration) / max(one.duration, 1e-300))
            for j, f in enumerate(fractions):
                err = abs(v["ALONG"][k * len(fractions) + j] - one.at(got * f)[0][0])
                single_pos = worse(single_pos, err / pos_tolerance(case, one.duration))
        # tests/unit/test_motion_jerk_matiec.py: durations to 1e-12, states to 1e-9;
        # test_motion_jerk_ruckig.py: durations to 1e-4, positions within float32 tolerance
        return [RefCheck("MotionJerkPlanner duration vs Ruckig", worse(dur, jog_dur), 1e-12,
                         "relative", tuple(failures)),
                RefCheck("MotionJerkAt positions vs Ruckig", pos, 1e-9, "unit"),
                RefCheck("MotionJerkGenerator state vs Ruckig.update", gen, 1e-9, "unit"),
                RefCheck(f"{len(singles)} single-axis plans: duration vs Ruckig", single_dur,
                         1e-4, "relative"),
                RefCheck(f"{len(singles)} single-axis plans: positions vs Ruckig", single_pos,
                         1.0, "of the float32 tolerance")]

    return ValueCase("Jerk-limited plan, jog and generator", program, reference)


@dataclass(frozen=True)
class CaseSpec:
    """A case by its PROGRAM's name, built on demand: some need a reference package (the
    Robotics Toolbox for the chain's targets, ahrs, Ruckig) that may be absent."""

    name: str
    build: Callable[[], ValueCase]
    needs: tuple[str, ...] = ()

    def missing(self) -> list[str]:
        return [m for m in self.needs if importlib.util.find_spec(m) is None]


SPECS = (
    CaseSpec("StrucppKinematics", kinematics_case),
    CaseSpec("StrucppWrap", wrap_case),
    CaseSpec("StrucppServo", mg996r_case),
    CaseSpec("StrucppPwm", pca9685_case),
    CaseSpec("StrucppFixedIk", fixed_ik_case),
    CaseSpec("StrucppAtan2", atan2_case),
    CaseSpec("StrucppSqrt", sqrt_case),
    CaseSpec("StrucppChain", chain_case, ("roboticstoolbox", "spatialmath")),
    CaseSpec("StrucppMadgwick", madgwick_case, ("ahrs", "scipy")),
    CaseSpec("StrucppJerk", jerk_case, ("ruckig",)),
)


def available_cases() -> dict[str, ValueCase]:
    """The cases whose reference packages are installed, by program name."""
    out = {}
    for spec in SPECS:
        if not spec.missing():
            case = spec.build()
            assert case.program.name == spec.name, (case.program.name, spec.name)
            out[spec.name] = case
    return out
