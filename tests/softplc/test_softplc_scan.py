"""Scan scheduling with step() at fake times, fault state, statistics, and the real-time
thread's start/stop (no assertions on speed)."""

from __future__ import annotations

import itertools
import threading
import time

import pytest
from softplc_fakes import MS, FakeProgram, copy_md_to_qw, task

from armbench.softplc import ModbusServer, PlcState, ProcessImage, SoftPlc, TaskSpec
from armbench.softplc.modbus_client import PlcClient
from armbench.softplc.scan import _percentile


def fake_clock(step_ns: int = 1000) -> itertools.count[int]:
    return itertools.count(0, step_ns)


def make(*tasks: TaskSpec, **kw: object) -> tuple[FakeProgram, SoftPlc]:
    program = FakeProgram(list(tasks), **kw)  # type: ignore[arg-type]
    clock = fake_clock()
    plc = SoftPlc(program, clock_ns=lambda: next(clock))
    plc.run()
    return program, plc


def test_tasks_release_at_multiples_of_their_interval() -> None:
    program, plc = make(task("fast", 10, priority=1), task("slow", 25, priority=0))
    t0 = 5_000 * MS  # the origin is the first step's time, not zero
    for ms in range(0, 101):
        plc.step(t0 + ms * MS)
    fast = [(now - t0) // MS for name, now in program.calls if name == "fast"]
    slow = [(now - t0) // MS for name, now in program.calls if name == "slow"]
    assert fast == list(range(0, 101, 10))
    assert slow == [0, 25, 50, 75, 100]
    stats = plc.stats()
    assert (stats["fast"].scans, stats["slow"].scans) == (11, 5)
    assert stats["fast"].overruns == stats["slow"].overruns == 0


def test_coarse_steps_run_each_due_task_once() -> None:
    program, plc = make(task("a", 10))
    assert plc.step(0) == ["a"]
    assert plc.step(3 * MS) == []
    assert plc.step(10 * MS) == ["a"]
    assert plc.next_release_ns() == 20 * MS


def test_late_task_counts_overruns_and_is_not_run_twice() -> None:
    program, plc = make(task("a", 10))
    plc.step(0)
    assert plc.step(45 * MS) == ["a"]  # release 10 ran 35 ms late; 20, 30, 40 were missed
    s = plc.stats()["a"]
    assert s.scans == 2 and s.overruns == 3
    assert s.jitter.max_ns == 35 * MS + 1000  # + the fake clock's 1 µs before the scan
    assert plc.next_release_ns() == 50 * MS  # back on the original grid
    assert plc.step(49 * MS) == []
    assert plc.step(50 * MS) == ["a"]
    assert plc.step(59 * MS) == []
    assert plc.step(69 * MS) == ["a"]  # 9 ms late: jitter, not an overrun
    assert plc.stats()["a"].overruns == 3


def test_priority_then_declaration_order() -> None:
    program, plc = make(
        task("low", 10, priority=5),
        task("high", 10, priority=0),
        task("mid_first", 10, priority=2),
        task("mid_second", 10, priority=2),
        task("slow_high", 20, priority=1),
    )
    order = ["high", "slow_high", "mid_first", "mid_second", "low"]
    assert plc.step(0) == order
    assert [name for name, _ in program.calls] == order
    assert plc.step(10 * MS) == ["high", "mid_first", "mid_second", "low"]
    assert plc.step(20 * MS) == order


def test_stopped_plc_does_not_scan() -> None:
    program = FakeProgram([task("a", 10)])
    plc = SoftPlc(program)
    assert plc.state is PlcState.STOPPED
    assert plc.step(0) == []
    plc.run()
    assert plc.step(100 * MS) == ["a"]
    plc.halt()
    assert plc.step(200 * MS) == []
    plc.run()  # new origin: the first step after run() runs everything
    assert plc.step(205 * MS) == ["a"]
    assert plc.next_release_ns() == 215 * MS


def test_statistics_with_fake_clock() -> None:
    program, plc = make(task("a", 10))
    for k in range(200):
        plc.step(k * 10 * MS + (k % 10) * 1000)  # jitter 0, 1, ..., 9 µs repeating
    s = plc.stats()["a"]
    assert s.scans == s.execution.count == s.jitter.count == 200
    # Each step reads the fake clock three times, 1 µs apart: t0 of the step, then scan
    # start and end, so every execution time is exactly 1 µs.
    assert s.execution.min_ns == s.execution.max_ns == s.execution.p99_ns == 1000
    # The scan starts 1 µs after the step began, on top of the lateness of now_ns.
    assert s.jitter.min_ns == 1000 and s.jitter.max_ns == 10_000
    assert s.jitter.mean_ns == pytest.approx(5500)
    assert s.jitter.p99_ns == 10_000 and s.jitter.p50_ns == 5000
    plc.reset_stats()
    assert plc.stats()["a"].scans == 0


def test_percentile_nearest_rank() -> None:
    samples = list(range(1, 101))
    assert _percentile(samples, 99.0) == 99
    assert _percentile(samples, 50.0) == 50
    assert _percentile(samples, 100.0) == 100
    assert _percentile([7], 99.0) == 7
    assert _percentile([], 99.0) == 0


def test_reservoir_bounds_memory() -> None:
    program = FakeProgram([task("a", 1)])
    plc = SoftPlc(program, reservoir=16)
    plc.run()
    for k in range(1000):
        plc.step(k * MS)
    s = plc.stats()["a"]
    assert s.scans == 1000


def test_program_validation() -> None:
    with pytest.raises(ValueError):
        SoftPlc(FakeProgram([]))
    with pytest.raises(ValueError):
        SoftPlc(FakeProgram([task("a", 10), task("a", 20)]))
    with pytest.raises(ValueError):
        SoftPlc(FakeProgram([TaskSpec("z", 0, 0, ())]))


def count_up(image: ProcessImage, now_ns: int) -> None:
    image.qw[0] += 1
    image.qx[0] ^= 1


def test_fault_stops_scans_and_keeps_restored_outputs() -> None:
    program, plc = make(
        task("main", 10, priority=0), task("other", 10, priority=1),
        bodies={"main": count_up}, fault_at={"main": 3},
    )
    plc.step(0)
    plc.step(10 * MS)
    assert program.image.qw[0] == 2
    assert plc.step(20 * MS) == []  # main faults first; 'other' is not run in that step
    assert plc.state is PlcState.FAULT
    fault = plc.fault
    assert fault is not None
    assert (fault.message, fault.location, fault.task) == (
        "division by zero", "controller.st:12:5", "main")
    assert program.image.qw[0] == 2 and program.image.qx[0] == 0  # restored by the "C side"
    calls = len(program.calls)
    assert plc.step(30 * MS) == [] and plc.step(1000 * MS) == []
    assert len(program.calls) == calls
    with pytest.raises(RuntimeError):
        plc.run()
    plc.reset_fault()
    assert plc.state is PlcState.STOPPED and plc.fault is None
    plc.run()
    assert plc.step(2000 * MS) == ["main", "other"]
    assert program.image.qw[0] == 3


def test_reset_fault_resume() -> None:
    program, plc = make(task("main", 10), fault_at={"main": 1})
    plc.step(0)
    assert plc.state is PlcState.FAULT
    plc.reset_fault(resume=True)
    assert plc.state is PlcState.RUNNING
    assert plc.step(7 * MS) == ["main"]  # new origin


def test_modbus_keeps_serving_in_fault() -> None:
    program, plc = make(task("main", 10), bodies={"main": count_up}, fault_at={"main": 2})
    with ModbusServer(program.image, plc.lock, port=0) as srv, PlcClient(port=srv.port) as c:
        plc.step(0)
        plc.step(10 * MS)
        assert plc.state is PlcState.FAULT
        assert c.read_holding_registers(0, 1) == [1]  # output as restored after the fault
        assert c.read_coils(0, 1) == [True]
        c.write_real(0, 2.5)  # writes still land in the image
        assert c.read_real(0) == 2.5
        plc.step(20 * MS)
        assert c.read_holding_registers(0, 1) == [1]  # and no scan ran


def test_instance_vars_passthrough() -> None:
    program, plc = make(task("main", 10))
    plc.step(0)
    assert plc.instance_vars("main_inst") == {"scans": 1, "instance": "main_inst"}


@pytest.mark.parametrize("fast_path", [True, False], ids=["compiled", "python"])
def test_fc16_lands_atomically_between_scans(fast_path: bool) -> None:
    """A scan thread copies %MD0..3 to %QW0..7 as fast as it can while the client writes all
    eight registers with one FC16; every scan and every read must see one write, never two
    (on both request paths of the server)."""
    words = 8
    torn_scans: list[tuple[int, ...]] = []
    copy = copy_md_to_qw(words // 2)

    def body(image: ProcessImage, now_ns: int) -> None:
        copy(image, now_ns)
        seen = tuple(image.qw[0:words])
        if len(set(seen)) != 1:
            torn_scans.append(seen)

    program = FakeProgram([task("copy", 1e-6)], bodies={"copy": body})
    plc = SoftPlc(program) if fast_path else SoftPlc(program, lock=threading.Lock())
    plc.run()
    stop = threading.Event()

    def scan_forever() -> None:
        fake_now = 0
        while not stop.is_set():
            plc.step(fake_now)
            fake_now += 1000
            time.sleep(0)  # hand the GIL over so the client's requests get through

    scanner = threading.Thread(target=scan_forever)
    with ModbusServer(program.image, plc.lock, port=0) as srv, PlcClient(port=srv.port) as c:
        assert srv.fast_path is fast_path
        scanner.start()
        try:
            for value in range(1, 301):
                c.write_registers(2048, [value] * words)
                scans_after_write = program.scans.get("copy", 0)
                # Wait for a scan that started after the write, so each write is scanned.
                deadline = time.monotonic() + 10
                while program.scans.get("copy", 0) < scans_after_write + 2:
                    assert time.monotonic() < deadline, "scan thread stalled"
                    time.sleep(0)
                seen = c.read_holding_registers(0, words)
                assert seen == [value] * words
        finally:
            stop.set()
            scanner.join(10)
    assert not torn_scans


def test_realtime_thread_runs_and_stops_without_leaks() -> None:
    before = set(threading.enumerate())
    program = FakeProgram([task("main", 2), task("slow", 5)], bodies={"main": count_up})
    plc = SoftPlc(program)
    with ModbusServer(program.image, plc.lock, port=0) as srv, PlcClient(port=srv.port) as c:
        plc.start()
        assert plc.thread_running and plc.state is PlcState.RUNNING
        with pytest.raises(RuntimeError):
            plc.start()
        deadline = time.monotonic() + 20
        while program.scans.get("main", 0) < 5 or program.scans.get("slow", 0) < 2:
            assert time.monotonic() < deadline, "real-time loop made no progress"
            time.sleep(0.005)
        assert c.read_holding_registers(0, 1)[0] >= 5
        plc.stop()
    assert plc.state is PlcState.STOPPED and not plc.thread_running
    s = plc.stats()["main"]
    assert s.scans >= 5 and s.jitter.min_ns >= 0
    assert set(threading.enumerate()) == before


def test_realtime_thread_survives_fault_and_resumes() -> None:
    before = set(threading.enumerate())
    program = FakeProgram([task("main", 1)], fault_at={"main": 3})
    plc = SoftPlc(program)
    plc.start()
    try:
        deadline = time.monotonic() + 20
        while plc.state is not PlcState.FAULT:
            assert time.monotonic() < deadline
            time.sleep(0.002)
        assert program.scans["main"] == 3
        plc.reset_fault(resume=True)
        while program.scans["main"] < 6:
            assert time.monotonic() < deadline
            time.sleep(0.002)
    finally:
        plc.stop()
    assert set(threading.enumerate()) == before


def test_run_realtime_for_a_duration_in_caller_thread() -> None:
    program = FakeProgram([task("main", 1)])
    plc = SoftPlc(program)
    plc.run_realtime(duration_s=0.2, spin_ns=0)  # long enough for a loaded machine
    assert program.scans["main"] >= 1
    with pytest.raises(ValueError):
        plc.run_realtime()


def test_rt_priority_request_is_safe_either_way() -> None:
    # In a throwaway thread: SCHED_FIFO sticks to the thread that asked for it.
    program = FakeProgram([task("main", 1)])
    plc = SoftPlc(program)
    worker = threading.Thread(
        target=plc.run_realtime, kwargs={"duration_s": 0.01, "rt_priority": 1}
    )
    worker.start()
    worker.join(10)
    assert not worker.is_alive()
    assert program.scans["main"] >= 1
    assert isinstance(plc.rt_priority_applied, bool)
