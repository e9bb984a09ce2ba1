#!/usr/bin/env python3
"""Independent pure-numpy RK4 of the fig1 (no control) model, compared to Basilisk.

Same model and initial conditions as fig1_truth.py (duplicated here on purpose,
so this file needs only numpy): point mass + J2 (analytic formula), cannonball
drag a = -1/2 rho C_D (A/m) |v| v with inertial v, exponential atmosphere,
classical RK4, fixed step.  Two density conventions:

* ``hold``  : rho evaluated at the START of each RK4 step (from r(t_k)) and held
              over the four stages -- what Basilisk does.
* ``stage`` : rho re-evaluated at every RK4 stage from the stage position.

Usage:
    python3 reference/basilisk/check_numpy.py \
        --csv reference/basilisk/fig1_truth_10s.csv [--dt 0.01] [--out-numpy X.csv]

Prints, per body, the max over all CSV times of |r_numpy - r_basilisk| (m) and
|v_numpy - v_basilisk| (m/s), and the values at the last time (360 s), for both
density conventions.  With --no-drag it compares against a gravity-only
Basilisk CSV (fig1_truth.py --no-drag).
"""

import argparse
import csv
import math
import sys

import numpy as np

MU = 3.986004418e14
RE = 6378137.0
J2 = 1.08262668e-3
CD = 2.2
RHO0 = 6.5003966907049361e-9
H_SCALE = 53628.0
MASS = np.array([10000.0, 640.1074, 1087.4786, 25.1687, 470.9405, 241.4649, 161.1994])
AREA = np.array([1000.0, 10.1267, 17.9324, 20.4416, 27.4020, 21.5405, 34.5757])
OFFSETS = np.array(
    [
        (3000.0, 0.0, 0.0),
        (0.0, 3500.0, 0.0),
        (0.0, 0.0, 4000.0),
        (-2500.0, 2500.0, 0.0),
        (2000.0, -3000.0, 1500.0),
        (-3000.0, -2000.0, -2500.0),
    ]
)


def initial_states():
    rp, ra = RE + 300e3, RE + 700e3
    a = 0.5 * (rp + ra)
    inc = math.pi / 6.0
    vp = math.sqrt(MU * (2.0 / rp - 1.0 / a))
    r0 = np.array([rp, 0.0, 0.0])
    v0 = np.array([0.0, vp * math.cos(inc), vp * math.sin(inc)])
    xh = r0 / np.linalg.norm(r0)
    zh = np.cross(r0, v0)
    zh /= np.linalg.norm(zh)
    yh = np.cross(zh, xh)
    C = np.column_stack([xh, yh, zh])
    r = np.vstack([r0, r0 + OFFSETS @ C.T])
    v = np.tile(v0, (7, 1))
    return r, v


def density(r):
    return RHO0 * np.exp(-(np.linalg.norm(r, axis=1) - RE) / H_SCALE)


def accel(r, v, rho, drag):
    rn = np.linalg.norm(r, axis=1)[:, None]
    z2 = (r[:, 2:3] / rn) ** 2
    a = -MU / rn**3 * r
    k = -1.5 * J2 * MU * RE**2 / rn**5
    a = a + k * np.hstack([r[:, 0:1] * (1 - 5 * z2), r[:, 1:2] * (1 - 5 * z2), r[:, 2:3] * (3 - 5 * z2)])
    if drag:
        vn = np.linalg.norm(v, axis=1)[:, None]
        a = a - 0.5 * (rho * CD * AREA / MASS)[:, None] * vn * v
    return a


def propagate(dt, duration, every, mode, drag=True):
    """Return {t_s: (r, v)} at multiples of `every`."""
    r, v = initial_states()
    n = int(round(duration / dt))
    k_every = int(round(every / dt))
    out = {0.0: (r.copy(), v.copy())}
    for k in range(n):
        if mode == "hold":
            rho = density(r)
            f = lambda rr, vv: accel(rr, vv, rho, drag)  # noqa: E731
        else:
            f = lambda rr, vv: accel(rr, vv, density(rr), drag)  # noqa: E731
        k1r, k1v = v, f(r, v)
        k2r, k2v = v + 0.5 * dt * k1v, f(r + 0.5 * dt * k1r, v + 0.5 * dt * k1v)
        k3r, k3v = v + 0.5 * dt * k2v, f(r + 0.5 * dt * k2r, v + 0.5 * dt * k2v)
        k4r, k4v = v + dt * k3v, f(r + dt * k3r, v + dt * k3v)
        r = r + dt / 6.0 * (k1r + 2 * k2r + 2 * k3r + k4r)
        v = v + dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
        if (k + 1) % k_every == 0:
            out[round((k + 1) * dt, 9)] = (r.copy(), v.copy())
    return out


def read_csv(path):
    data = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            t = round(float(row["t_s"]), 9)
            b = int(row["body"])
            r = [float(row[c]) for c in ("r_x_m", "r_y_m", "r_z_m")]
            v = [float(row[c]) for c in ("v_x_mps", "v_y_mps", "v_z_mps")]
            data.setdefault(t, {})[b] = (np.array(r), np.array(v))
    return data


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csv", default="reference/basilisk/fig1_truth_10s.csv")
    ap.add_argument("--dt", type=float, default=0.01)
    ap.add_argument("--no-drag", action="store_true")
    ap.add_argument("--out-numpy", default=None, help="also write the 'hold' numpy trajectory CSV")
    args = ap.parse_args()

    bsk = read_csv(args.csv)
    times = sorted(bsk)
    duration, every = times[-1], times[1] - times[0]
    for mode in ("hold", "stage"):
        sol = propagate(args.dt, duration, every, mode, drag=not args.no_drag)
        print(f"density mode = {mode!r}  (numpy RK4 dt={args.dt} vs Basilisk {args.csv})")
        print(" body  max|dr| all t [m]  |dr| @ t_end [m]  max|dv| all t [m/s]  |dv| @ t_end [m/s]")
        for b in range(7):
            dr = [np.linalg.norm(sol[t][0][b] - bsk[t][b][0]) for t in times]
            dv = [np.linalg.norm(sol[t][1][b] - bsk[t][b][1]) for t in times]
            print(f" {b:4d}  {max(dr):17.3e}  {dr[-1]:16.3e}  {max(dv):19.3e}  {dv[-1]:18.3e}")
        if mode == "hold" and args.out_numpy:
            with open(args.out_numpy, "w") as f:
                f.write("t_s,body,r_x_m,r_y_m,r_z_m,v_x_mps,v_y_mps,v_z_mps\n")
                for t in times:
                    for b in range(7):
                        r, v = sol[t][0][b], sol[t][1][b]
                        f.write(f"{t!r},{b}," + ",".join(repr(float(x)) for x in (*r, *v)) + "\n")
    # Size of the effect being tested: how far the 'hold' and 'stage' runs are apart.
    return 0


if __name__ == "__main__":
    sys.exit(main())
