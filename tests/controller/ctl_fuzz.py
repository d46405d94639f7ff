"""Seeded random programs against the stepped controller (stepped_controller.py), checked
every scan: random interleavings of every command code 1..46 and junk codes from up to four
clients whose blocks land in the same scan, hostile arguments (NaN, +/-Inf, +/-1e30, 0,
negative, 1e-30, huge, odd NaN payloads, -0.0), calibration and limit changes in the middle
of motions, Relax and Stop storms, takeovers (other sessions writing into owned mailboxes) and
waits of 1..50 scans. The monitors check promise A (steps, step changes, pulse ranges, travel,
finite registers), B's Stop-to-rest bound and that no answer goes to the wrong client.

One program is a pure function of its seed, so a failure is replayed by its seed. The pytest
test (test_controller_stateful.py) and bench/controller_stateful.py both call :func:`run`.
"""

from __future__ import annotations

import math
import random
import time
from dataclasses import dataclass, field

from stepped_controller import (
    HELLO,
    INIT_PWM,
    MAILBOXES,
    AnswerMonitor,
    Arg,
    Bits,
    CheckFormula,
    Client,
    OutputMonitor,
    SteppedController,
    StopMonitor,
    check_crc,
)

from armbench.softplc.loader import LoadedProgram

HOSTILE: tuple[Arg, ...] = (
    math.nan, math.inf, -math.inf, 1e30, -1e30, 0.0, -1.0, -250.0, 1e-30, -1e-30, 3.0e38,
    1e20, Bits(0x7FA00001), Bits(0xFFC00000), Bits(0x80000000), 1e6, -1e6)
JUNK_CODES = (0, -1, 18, 19, 23, 24, 25, 29, 34, 39, 47, 49, 99, 1000, -2147483648, 2147483647)


def _u(rng: random.Random, lo: float, hi: float) -> float:
    return rng.uniform(lo, hi)


def _log(rng: random.Random, lo: float, hi: float) -> float:
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def _joints(rng: random.Random) -> list[float]:
    # inside (mostly) and a little beyond the default travels: Base -60..60, Shoulder 10..130,
    # Elbow 5..125 (zero offsets 0, 70, 65)
    return [_u(rng, -70.0, 70.0), _u(rng, 0.0, 140.0), _u(rng, -5.0, 135.0)]


def _xyz(rng: random.Random) -> list[float]:
    return [_u(rng, 60.0, 240.0), _u(rng, -150.0, 150.0), _u(rng, 0.0, 220.0)]


def plausible(rng: random.Random, code: int) -> tuple[int, int, list[Arg]]:
    """(Int1, Int2, args) a well-meaning client might send with this code."""
    r = rng
    args: list[Arg]
    int1 = int2 = 0
    if code in (1, 20, 21):
        args = list(_xyz(r))
        int1 = r.choice((0, 0, 1))
    elif code == 2:
        args = list(_joints(r))
    elif code == 5:
        int1 = r.choice((0, 1, 2, 3, 4, 5, 5, 0, 6, -1))
        int2 = r.choice((1, 1, 1, -1, 0, 2))
        zero = {1: 70.0, 2: 65.0}.get(int1, 0.0) + r.choice((0.0, 0.0, _u(r, -40.0, 40.0)))
        lo_a = r.choice((-60.0, -45.0, _u(r, -90.0, -10.0)))
        hi_a = r.choice((60.0, 45.0, _u(r, 10.0, 90.0)))
        scale = r.choice((1000.0 / 120.0, _u(r, 4.0, 16.0)))
        centre = r.choice((1500.0, _u(r, 1200.0, 1800.0)))
        args = [zero, centre + lo_a * scale, centre + hi_a * scale, lo_a, hi_a]
    elif code in (6, 22):
        int2 = r.choice((1, 5, 32, 0, 33))
        int1 = r.choice((0, 1))
        args = []
    elif code == 11:
        args = [*_joints(r), _log(r, 5.0, 400.0), _log(r, 20.0, 5000.0),
                r.choice((_log(r, 100.0, 1e5), _log(r, 0.1, 1e9)))]
        int1 = r.choice((0, 1, 2, 3, 3, -1, 4, 4, 4, 5))
    elif code == 12:
        args = [*_xyz(r), _log(r, 5.0, 300.0), _log(r, 20.0, 3000.0), _u(r, 0.2, 3.0)]
        int1 = r.choice((0, 1, 2, 2, 3))
        int2 = r.choice((0, 0, 1))
    elif code == 13:
        args = [_u(r, -1.2, 1.2), _u(r, -1.2, 1.2), _u(r, -1.2, 1.2), _log(r, 5.0, 300.0),
                _log(r, 20.0, 3000.0), r.choice((0.0, 0.0, _log(r, 10.0, 1e7)))]
        int2 = r.choice((0, 0, 1))
    elif code == 14:
        args = [_u(r, -1.2, 1.2), _u(r, -1.2, 1.2), _u(r, -1.2, 1.2)]
    elif code == 16:
        args = [r.choice((0.0, 0.0, 100.0, 50.0, 1e-3, 500.0, 5000.0, 1e6))]
    elif code == 17:
        int1 = r.choice((0, 1, 2, 3, 4, 5, 6))
        args = [_log(r, 0.05, 3000.0), _log(r, 5.0, 2e5)]
    elif code in (30, 31):
        args = [_u(r, 100.0, 220.0), _u(r, -80.0, 80.0), _u(r, 20.0, 180.0)]
        if code == 30:
            args += [_u(r, -60.0, 60.0), _u(r, -60.0, 60.0)]
        else:
            args += [_u(r, -1.0, 1.0), _u(r, -1.0, 1.0), _u(r, -1.0, 1.0)]
            int2 = r.randint(-9000, 9000)
        int1 = r.randint(0, 3)
    elif code == 32:
        args = [_u(r, -60.0, 60.0), _u(r, -60.0, 60.0), r.choice((0.0, _u(r, 5.0, 200.0))),
                r.choice((0.0, _u(r, 20.0, 2000.0)))]
        int1 = r.choice((0, 2, 2, 3))
    elif code == 33:
        args = [r.choice((0.0, 100.0, _u(r, 0.0, 100.0), _u(r, -10.0, 110.0)))]
    elif code == 40:
        int1 = r.randint(0, 4)
        args = [r.choice((0.0, _u(r, 0.0, 1.0)))]
    elif code == 41:
        args = [r.choice((0.01, 0.02, _u(r, 0.0, 1.5)))]
    elif code in (42, 43, 44):
        args = [_u(r, -2.0, 2.0) + (1.0 if code == 43 else 0.0) for _ in range(3)]
    elif code == 45:
        int2 = r.choice((0, 1, 2))
        args = [_u(r, -1.0, 1.0) for _ in range(4)]
    elif code == 46:
        int1 = r.choice((0, 1, 3, 4))
        int2 = r.choice((0, 0, r.randint(1, 1_000_000), -1))
        args = [r.choice((0.0, 2.0)), r.choice((0.0, 90.0)), 0.0, 0.0, 0.0, 0.0]
    else:
        args = [_u(r, -100.0, 100.0) for _ in range(r.randint(0, 6))]
    return int1, int2, args


# command codes and how often a client picks them (Relax/Stop storms, motions and the
# calibration/limit changes weigh most; InitPwm rarely)
_CODES: tuple[tuple[int, float], ...] = (
    (1, 4.0), (2, 6.0), (3, 0.15), (4, 5.0), (5, 3.0), (6, 0.5), (7, 0.5), (8, 0.5), (9, 0.5),
    (10, 1.0), (11, 5.0), (12, 3.0), (13, 4.0), (14, 3.0), (15, 2.0), (16, 5.0), (17, 3.0),
    (20, 0.5), (21, 1.5), (22, 0.5), (30, 2.0), (31, 1.5), (32, 2.5), (33, 4.0), (40, 0.3),
    (41, 0.3), (42, 0.3), (43, 0.3), (44, 0.3), (45, 0.3), (46, 0.5), (-999, 1.0))


@dataclass
class FuzzReport:
    seed: int
    scans: int = 0
    commands: int = 0
    answered: int = 0
    wall_s: float = 0.0
    output: OutputMonitor | None = None
    stop: StopMonitor | None = None
    answers: AnswerMonitor | None = None
    results: dict[int, int] = field(default_factory=dict)  # result code -> count

    @property
    def violations(self) -> list[str]:
        out: list[str] = []
        if self.output is not None:
            out += [str(v) for v in self.output.violations]
        if self.stop is not None:
            out += [str(v) for v in self.stop.violations]
        if self.answers is not None:
            out += self.answers.violations
        return out

    def first_violation(self) -> str | None:
        """The violation of the earliest scan."""
        cands: list[tuple[int, str]] = []
        if self.output is not None and self.output.violations:
            v = self.output.violations[0]
            cands.append((v.scan, f"A: {v}"))
        if self.stop is not None and self.stop.violations:
            v = self.stop.violations[0]
            cands.append((v.scan, f"B: {v}"))
        if self.answers is not None and self.answers.violations:
            text = self.answers.violations[0]
            cands.append((int(text.split(",")[0].split()[1]), f"answers: {text}"))
        return min(cands)[1] if cands else None

    def format(self) -> str:
        lines = [f"seed {self.seed}: {self.scans} scans checked, {self.commands} commands sent "
                 f"({self.answered} answered), {self.wall_s:.1f} s"]
        top = sorted(self.results.items(), key=lambda kv: -kv[1])[:8]
        lines.append("  results: " + ", ".join(f"{code}: {n}" for code, n in top))
        if self.output is not None:
            lines.append("  " + self.output.report().replace("\n", "\n  "))
        if self.stop is not None:
            lines.append("  " + self.stop.report())
        if self.answers is not None:
            lines.append(f"  answers watched {self.answers.answers}")
        first = self.first_violation()
        lines.append(f"  violations: {len(self.violations)}"
                     + (f"; first: {first}" if first else ""))
        return "\n".join(lines)


@dataclass
class _Player:
    client: Client
    unanswered: int = 0


def _wait(rng: random.Random) -> int:
    x = rng.random()
    if x < 0.5:
        return rng.randint(1, 3)
    if x < 0.8:
        return rng.randint(4, 15)
    return rng.randint(16, 50)


def run(program: LoadedProgram, seed: int, *, max_scans: int | None = None,
        seconds: float | None = None, check_formula: CheckFormula = check_crc,
        stop_at_first: bool = True) -> FuzzReport:
    """One seeded random program until max_scans scans or `seconds` of wall time (whichever
    comes first), or the first violation when stop_at_first."""
    if max_scans is None and seconds is None:
        raise ValueError("give max_scans or seconds")
    rng = random.Random(seed)
    ctl = SteppedController(program, check_formula)
    out = OutputMonitor()
    stop = StopMonitor(out)
    answers = AnswerMonitor()
    ctl.observers += [out, stop, answers]
    report = FuzzReport(seed, output=out, stop=stop, answers=answers)
    players = [_Player(Client(ctl, m, rng.randint(1, 2**31 - 1))) for m in (1, 2, 3, 4)]
    codes = [c for c, _ in _CODES]
    weights = [w for _, w in _CODES]
    t0 = time.perf_counter()

    def done() -> bool:
        if max_scans is not None and ctl.scan >= max_scans:
            return True
        if seconds is not None and time.perf_counter() - t0 >= seconds:
            return True
        return stop_at_first and bool(report.violations)

    # most programs start after a few idle scans, some in the very first scan
    ctl.step(rng.choice((0, 1, 3, 5, 10)))
    while not done():
        # a client whose block was lost (overwritten, BadSequence) says Hello; one whose
        # mailbox another session holds moves to a free one
        for p in players:
            a = ctl.answer(p.client.mailbox)
            if a.owner not in (0, p.client.session):
                used = {q.client.mailbox for q in players}
                free = [m for m in range(1, MAILBOXES + 1)
                        if m not in used and ctl.answer(m).owner == 0]
                if free:
                    p.client.mailbox = rng.choice(free)
                    p.unanswered = 0
        movers = rng.sample(players, rng.choice((1, 1, 1, 2, 2, 3, 4)))
        for p in movers:
            last = p.client.result()
            if p.client.last is not None and (last is None or last == 105):
                p.unanswered += 1
            else:
                p.unanswered = 0
            if p.unanswered >= 1 and rng.random() < 0.7:
                p.client.send(HELLO)
            else:
                code = rng.choices(codes, weights)[0]
                if code == -999:
                    code = rng.choice(JUNK_CODES)
                if code == INIT_PWM and ctl.scan < 200:
                    code = HELLO
                int1, int2, args = plausible(rng, code)
                args = [rng.choice(HOSTILE) if rng.random() < 0.12 else x for x in args]
                if rng.random() < 0.03:
                    int1 = rng.choice((-2147483648, 2147483647, -1, 99))
                p.client.send(code, int1, int2, args)
            report.commands += 1
        if rng.random() < 0.04:
            # a takeover: another session writes a whole block into a client's mailbox
            victim = rng.choice(players)
            code = rng.choices(codes, weights)[0]
            code = rng.choice(JUNK_CODES) if code == -999 else code
            int1, int2, args = plausible(rng, code)
            ctl.write_block(victim.client.mailbox, rng.randint(1, 2**31 - 1),
                            rng.randint(1, 1000), code, int1, int2, args)
            report.commands += 1
        for _ in range(_wait(rng)):
            ctl.step()
            report.answered += len(ctl.answered)
            for done_blk in ctl.answered:
                report.results[done_blk.result] = report.results.get(done_blk.result, 0) + 1
            if done():
                break
    report.scans = ctl.scan
    report.wall_s = time.perf_counter() - t0
    return report

