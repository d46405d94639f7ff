"""The front ends of many files shared with a forked child (armbench.compiler.front_split).

The split runs in fresh single-threaded processes here, as in `armbench` and the benchmarks:
the test workers hold threads of their own, and there nothing forks (tested too). Each case
checks the results against the files' front ends computed one by one in the same process."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from armbench.compiler import front_split

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "sim"


def run_script(body: str, tmp_path: Path) -> dict[str, object]:
    """Run ``body`` in a new Python process; it prints one JSON object, returned here."""
    script = tmp_path / "split_case.py"
    script.write_text(f"import sys\nsys.path.insert(0, {str(SIM)!r})\n" + textwrap.dedent(body))
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return dict(json.loads(proc.stdout.strip().splitlines()[-1]))


def test_library_front_ends_split_equal_the_serial_ones(tmp_path: Path) -> None:
    out = run_script(f"""
        import json, pickle
        from pathlib import Path
        from armbench.compiler import front_split
        from armbench.compiler.units import FileFront, UnitCache, front_end
        files = sorted(Path({str(ROOT / "st")!r}).glob("*.st"))
        jobs = [(p, p.read_bytes()) for p in files]
        assert front_split.can_split([len(d) for _, d in jobs])
        split = front_split.compute_all(jobs, front_end, FileFront)
        def same(a, b):  # the same trees, positions and diagnostics; each pickled after one
            # round trip, so that the objects two nodes share are shared alike in both
            def again(x):
                return pickle.dumps(pickle.loads(pickle.dumps(x)))
            return again(a) == again(b)
        serial = [front_end(p, d) for p, d in jobs]
        # through the unit cache: the child's pickled bytes are its entries, read back as hits
        cache = UnitCache(folder=Path("cache"))
        first = cache.fronts(files)
        again = UnitCache(folder=Path("cache"))
        import armbench.compiler.units as units
        def no_work(*args):
            raise AssertionError("a cached file was computed again")
        units.front_end = no_work
        hits = again.fronts(files)
        print(json.dumps({{
            "files": len(files),
            "by_child": sum(c.pickled is not None for c in split),
            "equal": all(same(s.value, r) for s, r in zip(split, serial)),
            "cached_equal": all(same(h, r) for h, r in zip(hits, serial)),
            "first_equal": all(same(f, r) for f, r in zip(first, serial)),
        }}))
    """, tmp_path)
    assert out["equal"] and out["first_equal"] and out["cached_equal"], out
    files = out["files"]
    assert isinstance(files, int) and isinstance(out["by_child"], int)
    assert 0 < out["by_child"] < files, out  # both processes did part of the work


_TOY = """
    import json, os
    from dataclasses import dataclass
    from pathlib import Path
    from armbench.compiler import front_split
    front_split.MIN_SPLIT_BYTES = 1
    PARENT = os.getpid()

    @dataclass
    class Result:
        name: str
        size: int

    jobs = [(Path(f"f{{i}}.st"), bytes(1000 + i)) for i in range(40)]
    def expected():
        return [(p.name, len(d)) for p, d in jobs]
    def report(results):
        print(json.dumps({{
            "ok": [(r.value.name, r.value.size) for r in results] == expected(),
            "by_child": sum(r.pickled is not None for r in results)}}))
    {case}
"""


def toy(case: str) -> str:
    return _TOY.format(case=textwrap.indent(textwrap.dedent(case), "    ").strip())


def test_a_child_that_dies_costs_nothing_but_time(tmp_path: Path) -> None:
    out = run_script(toy("""
        import time
        def work(path, data):
            if os.getpid() != PARENT and path.name == "f30.st":
                os._exit(3)  # the child crashes after it sent f39 .. f31
            time.sleep(0.01)
            return Result(path.name, len(data))
        report(front_split.compute_all(jobs, work, Result))
    """), tmp_path)
    assert out["ok"], out


# what the child does instead of its work: nothing of it reaches the results
_CHILD_FAULTS = {
    "sends what is not a result": 'return "not a Result"',
    "raises": 'raise ValueError("the child\'s")',
}


@pytest.mark.parametrize("fault", sorted(_CHILD_FAULTS))
def test_what_the_child_sends_is_checked(tmp_path: Path, fault: str) -> None:
    out = run_script(toy(f"""
        import time
        def work(path, data):
            if os.getpid() != PARENT:
                {_CHILD_FAULTS[fault]}
            time.sleep(0.005)
            return Result(path.name, len(data))
        report(front_split.compute_all(jobs, work, Result))
    """), tmp_path)
    assert out == {"ok": True, "by_child": 0}


def test_a_child_that_hangs_is_not_waited_for(tmp_path: Path) -> None:
    out = run_script(toy("""
        import time
        front_split.STALL_S = 0.5
        def work(path, data):
            if os.getpid() != PARENT and path.name == "f35.st":
                time.sleep(3600)  # stuck after it sent f39 .. f36
            time.sleep(0.01)
            return Result(path.name, len(data))
        began = time.monotonic()
        results = front_split.compute_all(jobs, work, Result)
        assert time.monotonic() - began < 30
        report(results)
    """), tmp_path)
    assert out["ok"], out


def test_the_work_is_shared(tmp_path: Path) -> None:
    out = run_script(toy("""
        import time
        def work(path, data):
            time.sleep(0.01)
            return Result(path.name, len(data))
        report(front_split.compute_all(jobs, work, Result))
    """), tmp_path)
    assert out["ok"], out
    assert isinstance(out["by_child"], int) and 5 <= out["by_child"] <= 35, out


def test_no_fork_where_it_is_unsafe_or_does_not_pay() -> None:
    big = [front_split.MIN_SPLIT_BYTES, 1]
    assert not front_split.can_split([front_split.MIN_SPLIT_BYTES - 2, 1])  # too small
    assert not front_split.can_split([front_split.MIN_SPLIT_BYTES * 2])  # one file
    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    try:
        assert not front_split.can_split(big)  # another thread runs
    finally:
        release.set()
        other.join()
