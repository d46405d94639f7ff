"""One orientation-filter update: compiled ST against the Python reference (ahrs 0.4.0), per
sample, measured side by side in one run (prints figures; not a test).

The ST is st/*.st compiled by the bench's compiler (REAL = float32, cc -O2); a kernel FB
(bench/kernels/orientation_kernel.st) runs 1,000 simulated IMU samples per pass through one
filter block, so the figure is the ST update itself, without a Python call per sample. The
same samples go one by one through ahrs's Madgwick.updateIMU / updateMARG (float64 numpy).
For scale, the cost of one ST update called from Python through cffi (what the unit tests
pay) is printed too. Both chains start from the same quaternion; the end quaternions are
compared so that the timed code is known to do the same work.

Run: .venv/bin/python bench/orientation_bench.py [--passes N]
"""

from __future__ import annotations

import argparse
import sys
import timeit
from collections.abc import Callable
from pathlib import Path

import numpy as np

from armbench.compiler import compile_files
from armbench.orientation import (
    MADGWICK_IMU_BETA,
    MADGWICK_MARG_BETA,
    physical_samples,
    quat_dict,
    quat_row,
    st_samples,
)
from armbench.plant.imu import HandTrajectory, ImuModel, simulate

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
N = 1000  # samples per pass (the kernel's array size)
METHODS = {"gyro only": (1, 0.0), "complementary": (2, 0.0),
           "Madgwick IMU": (3, MADGWICK_IMU_BETA), "Madgwick MARG": (4, MADGWICK_MARG_BETA)}


def best(fn: Callable[[], object], repeat: int) -> float:
    """Best of ``repeat`` single runs, s."""
    return min(timeit.repeat(fn, number=1, repeat=repeat))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench/orientation_bench.py")
    parser.add_argument("--passes", type=int, default=200,
                        help="passes of 1000 samples per ST timing (default 200)")
    args = parser.parse_args(argv)
    if args.passes < 1:
        parser.error("--passes must be >= 1")
    try:
        from ahrs.filters import Madgwick
    except ImportError:
        print("ahrs is not installed: pip install -e '.[dev]' (it pins ahrs==0.4.0)")
        return 2

    mod = compile_files([*sorted((ROOT / "st").glob("*.st")),
                         HERE / "kernels" / "orientation_kernel.st"])
    record = simulate(HandTrajectory(), ImuModel(), duration_s=(N - 1) / 100.0, rate_hz=100.0,
                      seed=5)
    samples = st_samples(mod, record)
    phys = physical_samples(samples)
    q0 = record.quat_true[0]
    kernel = mod.new_fb("OrientationKernel")
    kernel.set(Samples=samples, InitialQuat=quat_dict(q0), PeriodS=record.period_s)

    print(f"one filter update per sample, {N} simulated MPU6050/HMC5883L samples "
          f"(best of 5 runs)\nST kernel = compiled ST, all samples inside one call; "
          f"ST via cffi = one Python call per sample")
    print(f"{'filter':15} {'ST kernel':>12} {'ST via cffi':>12} {'ahrs 0.4.0':>12} "
          f"{'ahrs / ST':>10}  end quaternions differ by")
    for name, (method, beta) in METHODS.items():
        kernel.set(Kind=method, Beta=beta, Repeats=1)
        kernel()
        st_final = np.array(quat_row(kernel.Final))
        kernel.set(Repeats=args.passes)
        st_us = best(kernel, 5) / (args.passes * (N - 1)) * 1e6

        block = {1: "GyroIntegrator", 2: "ComplementaryFilter", 3: "MadgwickImu",
                 4: "MadgwickMarg"}[method]
        fb = mod.new_fb(block)

        def via_cffi(fb: object = fb, beta: float = beta, method: int = method) -> None:
            params: dict[str, object] = {"SamplePeriodS": record.period_s, "Reset": True}
            if method in (3, 4):
                params["Beta"] = beta
            if method != 2:  # ComplementaryFilter starts from its first sample instead
                params["InitialQuat"] = quat_dict(q0)
            fb(**params)  # type: ignore[operator]
            for s in samples[1:]:
                fb(Reset=False, Sample=s)  # type: ignore[operator]

        cffi_us = best(via_cffi, 3) / (N - 1) * 1e6

        if method in (3, 4):
            ref = Madgwick(Dt=record.period_s, gain=beta)
            gyr = np.radians(phys.gyro_dps)

            def run_ahrs(ref: object = ref, method: int = method,
                         gyr: np.ndarray = gyr) -> np.ndarray:
                q = q0.copy()
                for k in range(1, N):
                    if method == 3:
                        q = ref.updateIMU(q, gyr[k], phys.accel_g[k])  # type: ignore[attr-defined]
                    else:
                        q = ref.updateMARG(q, gyr[k], phys.accel_g[k],  # type: ignore[attr-defined]
                                           phys.mag_gauss[k])
                return q

            ahrs_us = best(run_ahrs, 5) / (N - 1) * 1e6
            ahrs_final = np.asarray(run_ahrs(), dtype=np.float64)
            diff = float(np.abs(ahrs_final - st_final).max())
            print(f"{name:15} {st_us:9.3f} us {cffi_us:9.2f} us {ahrs_us:9.2f} us "
                  f"{ahrs_us / st_us:9.0f}x  {diff:.1e}")
        else:
            print(f"{name:15} {st_us:9.3f} us {cffi_us:9.2f} us {'(no twin)':>12}")
    print("ahrs has no twin of the seed's quaternion complementary filter (its Complementary "
          "blends Euler angles).")
    return 0


if __name__ == "__main__":
    sys.exit(main())
