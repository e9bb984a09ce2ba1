#!/usr/bin/env python3
"""Basilisk truth trajectory for Cohort's "fig1" scenario, WITHOUT control.

What it models
--------------
Seven independent point-mass spacecraft (body 0 = defunct, 1..6 = servicers,
"fig1-fixed" initial conditions) around a non-rotating Earth, each subject to

* gravity: point mass + J2 only, through Basilisk's spherical-harmonics gravity
  model (``SphericalHarmonicsGravityModel``, degree 2) with
  mu = 3.986004418e14 m^3/s^2, R_e = 6 378 137 m and the single non-zero
  fully-normalised coefficient C20bar = -J2/sqrt(5), J2 = 1.08262668e-3.
  The coefficient file is written by this script (JPL/GGM format, the format
  Basilisk's ``loadGravFromFile`` reads) into a temporary directory; mu and
  R_e are set on the ``GravBodyData`` too, because Basilisk's
  ``initializeParameters(body)`` overwrites the file's mu/R_e with the body's.
  No planet ephemeris/orientation message is connected, so the planet-fixed
  frame is the inertial frame (identity DCM); J2 is axisymmetric anyway.
  The script checks the resulting acceleration against the analytic
  point-mass + J2 formula at the defunct's initial position and prints the
  relative error (it aborts if it exceeds 1e-12).
* drag: Basilisk ``DragDynamicEffector`` in "cannonball" mode,
  a = -1/2 rho C_D (A/m) |v| v, C_D = 2.2, A/m per body, fed by an
  ``ExponentialAtmosphere`` with baseDensity = 6.5003966907049361e-9 kg/m^3,
  scaleHeight = 53 628 m, planetRadius = 6 378 137 m, i.e.
  rho = 6.5003966907049361e-9 * exp(-(|r| - 6378137)/53628).
* integrator: ``svIntegratorRK4`` (classical RK4), fixed step --dt (0.01 s),
  one integration step per task call, 360 s.

Basilisk conventions found (source read: AVSLab/basilisk
``src/simulation/dynamics/dragEffector/dragDynamicEffector.cpp``,
``src/simulation/environment/_GeneralModuleFiles/atmosphereBase.cpp``,
``.../ExponentialAtmosphere/exponentialAtmosphere.cpp``,
``src/simulation/dynamics/gravityEffector/sphericalHarmonicsGravityModel.cpp``,
``src/simulation/dynamics/_GeneralModuleFiles/gravityEffector.cpp``,
``src/simulation/dynamics/spacecraft/spacecraft.cpp``):

* Drag velocity: ``updateDragDir()`` uses the hub's INERTIAL velocity state
  ``v_BN_N`` (rotated into the body frame and back).  Only if the optional
  ``windVelInMsg`` is linked is a wind/co-rotation velocity subtracted; it is
  not linked here, so drag uses the inertial velocity, re-evaluated at every
  RK4 stage (it reads the stage state).  No planet rotation enters drag or the
  exponential atmosphere (altitude = |r_sc - r_planet| - planetRadius).
* Density hold: the atmosphere module computes rho once per task call from
  the spacecraft state MESSAGE, and the drag effector copies it in its
  ``UpdateState`` ("conditions are held piecewise-constant over an
  integration step").  With the module priorities used here
  (atmosphere > drag > spacecraft), the step t_k -> t_k+dt uses
  rho(|r(t_k)|): density evaluated at the START of each RK4 step and held over
  all four stages.  Order matters: with the atmosphere before the spacecraft
  but the drag effector after it, rho lags one step (rho(r(t_k - dt)));
  measured: up to 0.42 mm at 360 s (body 3) vs the start-of-step convention.
  Stage velocities are used for |v| v at every stage (only rho is held).
* Spacecraft integrate "backwards": the call at time t integrates from the
  previous call's time up to t and then writes the state message at t.

How to run
----------
    pip install bsk==2.12.1
    python3 reference/basilisk/fig1_truth.py --out reference/basilisk/fig1_truth_10s.csv

Options: --dt (integration step, s; default 0.01), --every (output interval,
s; default 10), --duration (s; default 360), --no-drag (diagnostic only).
CSV columns: t_s,body,r_x_m,r_y_m,r_z_m,v_x_mps,v_y_mps,v_z_mps (ECI, SI),
numbers printed with repr() (round-trip precision).
"""

import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np

from Basilisk.simulation import (
    dragDynamicEffector,
    exponentialAtmosphere,
    spacecraft,
    svIntegrators,
)
from Basilisk.utilities import SimulationBaseClass, macros, simIncludeGravBody

# ---------------------------------------------------------------- constants
MU = 3.986004418e14  # m^3/s^2
RE = 6378137.0  # m
J2 = 1.08262668e-3
CD = 2.2
RHO0 = 6.5003966907049361e-9  # kg/m^3 at |r| = RE
H_SCALE = 53628.0  # m

# (mass kg, cross-section m^2); body 0 = defunct, 1..6 = servicers
BODIES = [
    (10000.0, 1000.0),
    (640.1074, 10.1267),
    (1087.4786, 17.9324),
    (25.1687, 20.4416),
    (470.9405, 27.4020),
    (241.4649, 21.5405),
    (161.1994, 34.5757),
]

# "fig1-fixed" LVLH offsets (x radial, y in-track, z cross-track), metres
OFFSETS = [
    (3000.0, 0.0, 0.0),
    (0.0, 3500.0, 0.0),
    (0.0, 0.0, 4000.0),
    (-2500.0, 2500.0, 0.0),
    (2000.0, -3000.0, 1500.0),
    (-3000.0, -2000.0, -2500.0),
]


def initial_states():
    """ECI initial (r, v) for the 7 bodies, shared with check_numpy.py."""
    rp = RE + 300e3
    ra = RE + 700e3
    a = 0.5 * (rp + ra)
    inc = math.pi / 6.0
    vp = math.sqrt(MU * (2.0 / rp - 1.0 / a))
    r0 = np.array([rp, 0.0, 0.0])
    v0 = np.array([0.0, vp * math.cos(inc), vp * math.sin(inc)])
    xh = r0 / np.linalg.norm(r0)
    h = np.cross(r0, v0)
    zh = h / np.linalg.norm(h)
    yh = np.cross(zh, xh)
    C = np.column_stack([xh, yh, zh])  # LVLH -> ECI
    states = [(r0.copy(), v0.copy())]
    for off in OFFSETS:
        states.append((r0 + C @ np.array(off), v0.copy()))
    return states


def analytic_grav(r):
    """Point mass + J2 acceleration (the plant's formula)."""
    x, y, z = r
    rn = math.sqrt(x * x + y * y + z * z)
    a_pm = -MU / rn**3 * np.asarray(r)
    k = -1.5 * J2 * MU * RE**2 / rn**5
    zz = 5.0 * z * z / (rn * rn)
    return a_pm + k * np.array([x * (1 - zz), y * (1 - zz), z * (3 - zz)])


def write_grav_file(path):
    """Degree-2 coefficient file in the GGM/JPL text format Basilisk reads.

    Header: R_e, mu, mu-uncertainty, maxDeg, maxOrder, normalized flag(1),
    ref lon, ref lat.  Rows: l, m, Cbar_lm, Sbar_lm, sigmaC, sigmaS.
    """
    c20 = -J2 / math.sqrt(5.0)
    with open(path, "w") as f:
        f.write(f"{RE!r}, {MU!r}, 0.0, 2, 2, 1, 0.0, 0.0\n")
        for l in range(3):
            for m in range(l + 1):
                c = 1.0 if (l, m) == (0, 0) else (c20 if (l, m) == (2, 0) else 0.0)
                f.write(f"{l}, {m}, {c!r}, 0.0, 0.0, 0.0\n")


def run(dt, every, duration, drag=True, verbose=True):
    """Run Basilisk; return (times list, dict body -> list of (r, v))."""
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("dynProc")
    task = "dynTask"
    dt_ns = macros.sec2nano(dt)
    proc.addTask(sim.CreateNewTask(task, dt_ns))

    # --- gravity: point mass + J2 via spherical harmonics, degree 2
    grav_factory = simIncludeGravBody.gravBodyFactory()
    earth = grav_factory.createEarth()
    earth.isCentralBody = True
    earth.mu = MU  # Basilisk default would be 3.98600436e14
    earth.radEquator = RE  # Basilisk default would be 6378136.6
    with tempfile.TemporaryDirectory(prefix="cohort_bsk_") as tmpdir:
        grav_path = os.path.join(tmpdir, "earth_J2_only.txt")
        write_grav_file(grav_path)
        # the file is parsed here, immediately
        earth.useSphericalHarmonicsGravityModel(grav_path, 2)

    # --- atmosphere (one module, one output message per spacecraft)
    atmo = exponentialAtmosphere.ExponentialAtmosphere()
    atmo.ModelTag = "expAtmo"
    atmo.baseDensity = RHO0
    atmo.scaleHeight = H_SCALE
    atmo.planetRadius = RE
    # Priorities: higher runs first. atmosphere (300) -> drag (200) ->
    # spacecraft (100) so step t_k -> t_k+dt uses rho(r(t_k)).
    sim.AddModelToTask(task, atmo, 300)

    scs, recs, drags = [], [], []
    for i, ((mass, area), (r0, v0)) in enumerate(zip(BODIES, initial_states())):
        sc = spacecraft.Spacecraft()
        sc.ModelTag = f"body{i}"
        sc.hub.mHub = mass
        sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
        sc.hub.IHubPntBc_B = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        sc.hub.r_CN_NInit = [[c] for c in r0]
        sc.hub.v_CN_NInit = [[c] for c in v0]
        sc.hub.sigma_BNInit = [[0.0], [0.0], [0.0]]
        sc.hub.omega_BN_BInit = [[0.0], [0.0], [0.0]]
        integ = svIntegrators.svIntegratorRK4(sc)
        sc.setIntegrator(integ)
        grav_factory.addBodiesTo(sc)
        atmo.addSpacecraftToModel(sc.scStateOutMsg)
        if drag:
            d = dragDynamicEffector.DragDynamicEffector()
            d.ModelTag = f"drag{i}"
            d.coreParams.projectedArea = area
            d.coreParams.dragCoeff = CD
            d.coreParams.comOffset = [0.0, 0.0, 0.0]
            d.atmoDensInMsg.subscribeTo(atmo.envOutMsgs[i])
            sc.addDynamicEffector(d)
            sim.AddModelToTask(task, d, 200)
            drags.append(d)
        sim.AddModelToTask(task, sc, 100)
        rec = sc.scStateOutMsg.recorder(macros.sec2nano(every))
        sim.AddModelToTask(task, rec, 0)
        scs.append(sc)
        recs.append((rec, integ))

    sim.InitializeSimulation()

    # --- gravity check against the analytic point-mass + J2 formula
    r_chk = initial_states()[0][0] + np.array([0.0, 1.0e5, 2.0e5])  # off-plane point
    for r_test in (initial_states()[0][0], r_chk):
        a_bsk = np.array(earth.gravityModel.computeField(list(r_test))).reshape(3)
        a_ref = analytic_grav(r_test)
        rel = np.linalg.norm(a_bsk - a_ref) / np.linalg.norm(a_ref)
        # J2 part alone, relative
        a_pm = -MU / np.linalg.norm(r_test) ** 3 * r_test
        rel_j2 = np.linalg.norm(a_bsk - a_ref) / np.linalg.norm(a_ref - a_pm)
        if verbose:
            print(
                f"gravity check at r={r_test.tolist()}: |a_bsk-a_ref|/|a_ref| = {rel:.3e}, "
                f"relative to J2 part = {rel_j2:.3e}",
                file=sys.stderr,
            )
        if rel > 1e-12:
            raise SystemExit("Basilisk gravity disagrees with the analytic J2 formula")

    sim.ConfigureStopTime(macros.sec2nano(duration))
    t0 = time.time()
    sim.ExecuteSimulation()
    wall = time.time() - t0
    if verbose:
        print(f"Basilisk ExecuteSimulation wall time: {wall:.1f} s", file=sys.stderr)

    out = {}
    times = None
    for i, (rec, _) in enumerate(recs):
        t = np.asarray(rec.times(), dtype=np.int64)
        r = np.asarray(rec.r_BN_N)
        v = np.asarray(rec.v_BN_N)
        if times is None:
            times = t
        assert np.array_equal(times, t)
        out[i] = (r, v)
    return times, out, wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="fig1_truth_10s.csv", help="output CSV path")
    ap.add_argument("--dt", type=float, default=0.01, help="RK4 step [s]")
    ap.add_argument("--every", type=float, default=10.0, help="output interval [s]")
    ap.add_argument("--duration", type=float, default=360.0, help="duration [s]")
    ap.add_argument("--no-drag", action="store_true", help="diagnostic: gravity only")
    args = ap.parse_args()

    times, out, _ = run(args.dt, args.every, args.duration, drag=not args.no_drag)
    n_expected = int(round(args.duration / args.every)) + 1
    if len(times) != n_expected:
        raise SystemExit(f"expected {n_expected} samples, got {len(times)}: {times}")
    with open(args.out, "w") as f:
        f.write("t_s,body,r_x_m,r_y_m,r_z_m,v_x_mps,v_y_mps,v_z_mps\n")
        for k, tn in enumerate(times):
            t_s = float(tn) * 1e-9
            t_s = float(round(t_s, 9))
            for b in range(len(BODIES)):
                r, v = out[b]
                vals = [repr(float(x)) for x in (*r[k], *v[k])]
                f.write(f"{t_s!r},{b}," + ",".join(vals) + "\n")
    print(f"wrote {args.out}: {len(times)} times x {len(BODIES)} bodies", file=sys.stderr)


if __name__ == "__main__":
    main()
