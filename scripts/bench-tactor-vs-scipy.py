#!/usr/bin/env python3
"""Peer comparison: the 10 s tactor simulation (physics.md §1, thesis-sim preset, unencased, b = 6.3e-8)
with scipy's solve_ivp (LSODA, rtol 1e-6, atol 1e-9) and with `vestnav sim tactor --json` (release build),
in one run. Prints each tool's mean omega over the window t = 5..10 s, its error against the reference
value (scipy DOP853 at rtol 1e-12: 833.5334 rad/s), the wall times and their ratio.

Usage: scripts/bench-tactor-vs-scipy.py [--vestnav PATH] [--repeat N]
Installs scipy with pip (--user) if it is missing. Build vestnav first: cargo build --release.
"""
import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

try:
    import numpy as np
    from scipy.integrate import solve_ivp
except ImportError:
    subprocess.check_call([sys.executable, "-m", "pip", "install", "--user", "scipy", "numpy"])
    import numpy as np
    from scipy.integrate import solve_ivp

REFERENCE_OMEGA_MEAN = 833.5334  # physics.md §1, scipy DOP853 rtol 1e-12
M, L_ECC, MT, KT, IND, R, U, B, G = 0.55e-3, 2.57e-3, 3.7e-3, 0.0019, 1.1e-3, 62.0, 3.3, 6.3e-8, 9.81


def rhs(_t, y):
    """[x, v, theta, omega, i]' with the 2x2 mass matrix solved (physics.md §1)."""
    _x, v, th, om, i = y
    s, c = math.sin(th), math.cos(th)
    f1 = M * L_ECC * om * om * s
    f2 = KT * i - B * om + M * G * L_ECC * s
    det = MT * M * L_ECC**2 - (M * L_ECC * c) ** 2
    v_dot = (M * L_ECC**2 * f1 - M * L_ECC * c * f2) / det
    om_dot = (MT * f2 - M * L_ECC * c * f1) / det
    return [v, v_dot, om, om_dot, (U - R * i - KT * om) / IND]


def run_scipy():
    t_eval = np.arange(0, 100001) * 1e-4
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, 10.0), [0.0] * 5, method="LSODA", rtol=1e-6, atol=1e-9, t_eval=t_eval)
    wall = time.perf_counter() - t0
    if not sol.success:
        sys.exit(f"scipy failed: {sol.message}")
    theta = sol.y[2]
    omega_mean = (theta[-1] - theta[50000]) / 5.0
    return omega_mean, wall


def run_vestnav(exe, repeat, extra):
    best = math.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        proc = subprocess.run([exe, "sim", "tactor", "--json", *extra], check=True, capture_output=True, text=True)
        best = min(best, time.perf_counter() - t0)
        out = json.loads(proc.stdout)
    return out["omega_mean_rad_s"], best


def main():
    root = Path(__file__).resolve().parent.parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vestnav", default=str(root / "target" / "release" / "vestnav"))
    ap.add_argument("--repeat", type=int, default=5, help="vestnav runs; the fastest counts")
    args = ap.parse_args()
    if not Path(args.vestnav).exists():
        sys.exit(f"{args.vestnav} not found: run `cargo build --release` first")
    w_sp, t_sp = run_scipy()
    w_vn, t_vn = run_vestnav(args.vestnav, args.repeat, [])
    # Equal accuracy: halving the step angle divides vestnav's RK4 error by ~16.
    w_eq, t_eq = run_vestnav(args.vestnav, args.repeat, ["--step-angle-rad", "0.13"])
    print(f"reference mean omega (DOP853 rtol 1e-12): {REFERENCE_OMEGA_MEAN:.4f} rad/s")
    print(f"{'tool':<52} {'mean omega':>12} {'rel. error':>11} {'wall time':>11}")
    for name, w, t in [
        ("scipy solve_ivp LSODA rtol 1e-6 atol 1e-9", w_sp, t_sp),
        ("vestnav sim tactor --json (default step 0.26 rad)", w_vn, t_vn),
        ("vestnav sim tactor --json --step-angle-rad 0.13", w_eq, t_eq),
    ]:
        print(f"{name:<52} {w:>12.4f} {abs(w / REFERENCE_OMEGA_MEAN - 1):>11.2e} {t * 1e3:>9.1f} ms")
    print(f"time ratio scipy / vestnav at default step: {t_sp / t_vn:.0f}x")
    print(f"time ratio scipy / vestnav at equal or better accuracy (0.13 rad): {t_sp / t_eq:.0f}x")
    print("(vestnav times are whole processes: start-up, 10 s simulation with traces, FFT, JSON)")


if __name__ == "__main__":
    main()
