"""Kinematic model of a TowerPro MG996R hobby servo driven by a PWM pulse width.

The paper behind the arm (document 002 in docs/sources.md) drives MG996R servos at 50 Hz with
1.0 ms = -60 deg, 1.5 ms = 0 deg and 2.0 ms = +60 deg. The model maps the pulse width linearly
through those two end points (configurable), clamps to the mechanical travel, and slews towards
the commanded angle at the rated no-load speed (0.17 s/60 deg at 4.8 V; 0.14 s/60 deg at 6 V).

Behaviour decisions:
* Deadband: the servo's controller ignores a pulse that differs from the pulse equivalent of
  its present position by no more than half the dead-band width (5 us on the MG996R sheet).
  Once it has started a move it runs all the way to the commanded angle, so it settles exactly
  on target instead of stopping at the band edge; a simplification of the real
  comparator-with-hysteresis that keeps the model deterministic and easy to test.
* Invalid or missing pulse (None, 0, or outside `valid_min_us..valid_max_us`, 500..2500 us by
  default): with `SignalLoss.LIMP` (default, what an analog-style MG996R does) the motor stops
  driving at once, torque goes off and the position stays where it is (no gravity or load is
  modelled here; the arm model can use `torque_on` for that). With `SignalLoss.HOLD` (what many
  digital servos do) the servo keeps acting on the last valid pulse.
* No acceleration or overshoot: constant-speed slew, the pulse is taken as present for the whole
  step, and the PWM frame rate is not checked.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

MG996R_SECONDS_PER_60DEG = 0.17  # rated no-load speed at 4.8 V


class SignalLoss(enum.Enum):
    """What the servo does when the pulse is missing or out of the valid window."""

    LIMP = "limp"  # torque off, stays where it is
    HOLD = "hold"  # keeps going to / holding the last valid command


@dataclass(frozen=True)
class ServoParams:
    """Calibration and limits of one servo; the defaults are the MG996R of document 002."""

    pulse_low_us: float = 1000.0
    angle_low_deg: float = -60.0
    pulse_high_us: float = 2000.0
    angle_high_deg: float = 60.0
    valid_min_us: float = 500.0
    valid_max_us: float = 2500.0
    seconds_per_60deg: float = MG996R_SECONDS_PER_60DEG
    deadband_width_us: float = 5.0
    min_angle_deg: float = -90.0
    max_angle_deg: float = 90.0
    signal_loss: SignalLoss = SignalLoss.LIMP

    def __post_init__(self) -> None:
        numbers = {
            name: getattr(self, name)
            for name in (
                "pulse_low_us",
                "angle_low_deg",
                "pulse_high_us",
                "angle_high_deg",
                "valid_min_us",
                "valid_max_us",
                "seconds_per_60deg",
                "deadband_width_us",
                "min_angle_deg",
                "max_angle_deg",
            )
        }
        for name, value in numbers.items():
            if not math.isfinite(value):
                raise ValueError(f"ServoParams.{name} must be a finite number, got {value!r}")
        if self.pulse_low_us == self.pulse_high_us or self.angle_low_deg == self.angle_high_deg:
            raise ValueError(
                "ServoParams needs two distinct calibration points: got "
                f"{self.pulse_low_us} us -> {self.angle_low_deg} deg and "
                f"{self.pulse_high_us} us -> {self.angle_high_deg} deg"
            )
        if not 0 < self.valid_min_us < self.valid_max_us:
            raise ValueError(
                f"valid pulse window must satisfy 0 < valid_min_us < valid_max_us, got "
                f"{self.valid_min_us}..{self.valid_max_us} us"
            )
        if self.seconds_per_60deg <= 0:
            raise ValueError(
                f"seconds_per_60deg must be > 0 (MG996R: 0.17 at 4.8 V), got "
                f"{self.seconds_per_60deg}"
            )
        if self.deadband_width_us < 0:
            raise ValueError(f"deadband_width_us must be >= 0, got {self.deadband_width_us}")
        if self.min_angle_deg >= self.max_angle_deg:
            raise ValueError(
                f"mechanical limits need min_angle_deg < max_angle_deg, got "
                f"{self.min_angle_deg}..{self.max_angle_deg}"
            )

    @property
    def deg_per_us(self) -> float:
        """Slope of the pulse-to-angle line (signed: negative for a reversed servo)."""
        return (self.angle_high_deg - self.angle_low_deg) / (self.pulse_high_us - self.pulse_low_us)

    @property
    def max_speed_deg_s(self) -> float:
        """Slew rate in degrees per second."""
        return 60.0 / self.seconds_per_60deg

    def angle_for_pulse(self, pulse_us: float) -> float:
        """Angle the pulse asks for, before the mechanical limits are applied."""
        return self.angle_low_deg + (pulse_us - self.pulse_low_us) * self.deg_per_us

    def pulse_for_angle(self, angle_deg: float) -> float:
        """Pulse width that asks for this angle (inverse of angle_for_pulse)."""
        return self.pulse_low_us + (angle_deg - self.angle_low_deg) / self.deg_per_us

    def pulse_is_valid(self, pulse_us: float | None) -> bool:
        """True when the servo electronics accept this pulse as a command."""
        return pulse_us is not None and self.valid_min_us <= pulse_us <= self.valid_max_us


@dataclass
class MG996R:
    """One servo's state. Advance it with step(); read angle_deg."""

    params: ServoParams = field(default_factory=ServoParams)
    initial_angle_deg: float = 0.0
    _angle_deg: float = field(init=False, repr=False)
    _target_deg: float = field(init=False, repr=False)
    _moving: bool = field(init=False, repr=False, default=False)
    _torque_on: bool = field(init=False, repr=False, default=False)

    def __post_init__(self) -> None:
        p = self.params
        if not (
            math.isfinite(self.initial_angle_deg)
            and p.min_angle_deg <= self.initial_angle_deg <= p.max_angle_deg
        ):
            raise ValueError(
                f"initial_angle_deg {self.initial_angle_deg!r} is outside the mechanical travel "
                f"{p.min_angle_deg}..{p.max_angle_deg} deg"
            )
        self._angle_deg = self.initial_angle_deg
        self._target_deg = self.initial_angle_deg

    @property
    def angle_deg(self) -> float:
        """Present output-shaft angle."""
        return self._angle_deg

    @property
    def target_deg(self) -> float:
        """Angle the servo is heading for (its present angle when idle or limp)."""
        return self._target_deg

    @property
    def moving(self) -> bool:
        """True while the servo is slewing towards target_deg."""
        return self._moving

    @property
    def torque_on(self) -> bool:
        """False until the first valid pulse, and while limp after losing the signal."""
        return self._torque_on

    def step(self, dt_s: float, pulse_us: float | None) -> float:
        """Advance dt_s seconds with this pulse width applied (None = no pulse); returns angle."""
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise ValueError(f"dt_s must be a finite, non-negative time in seconds, got {dt_s!r}")
        if pulse_us is not None and not math.isfinite(pulse_us):
            raise ValueError(f"pulse_us must be a finite width in us or None, got {pulse_us!r}")
        p = self.params
        if p.pulse_is_valid(pulse_us):
            assert pulse_us is not None
            self._command(pulse_us)
        elif p.signal_loss is SignalLoss.LIMP:
            self._torque_on = False
            self._moving = False
            self._target_deg = self._angle_deg
        # SignalLoss.HOLD: keep acting on the last valid command, i.e. change nothing here.
        if self._moving:
            remaining = self._target_deg - self._angle_deg
            travel = p.max_speed_deg_s * dt_s
            if abs(remaining) <= travel:
                self._angle_deg = self._target_deg
                self._moving = False
            else:
                self._angle_deg += math.copysign(travel, remaining)
        return self._angle_deg

    def _command(self, pulse_us: float) -> None:
        p = self.params
        self._torque_on = True
        wanted = min(max(p.angle_for_pulse(pulse_us), p.min_angle_deg), p.max_angle_deg)
        if self._moving:
            self._target_deg = wanted
            return
        # The controller compares pulse widths, so the dead band is in us, not degrees.
        error_us = abs(pulse_us - p.pulse_for_angle(self._angle_deg))
        if error_us > p.deadband_width_us / 2 and wanted != self._angle_deg:
            self._target_deg = wanted
            self._moving = True
