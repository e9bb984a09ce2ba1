"""A plant written in Python: spacecraft near a circular reference orbit, in its LVLH (Hill)
frame, x radial, y in-track, z orbit normal, under the Clohessy-Wiltshire equations

    x'' = 3 n^2 x + 2 n y' + u_x,   y'' = -2 n x' + u_y,   z'' = -n^2 z + u_z

integrated with RK4 (the command held over the step). Each agent reads its own position with
zero-mean Gaussian noise drawn from the generator Cohort hands over, so the draws are the same in
every run mode. Flown by Cohort's Rust `consensus-formation` agents in examples/python/hcw-ring.toml.
"""
import math

import numpy as np

MU_EARTH_M3PS2 = 3.986004418e14
R_EARTH_M = 6378137.0


class HillFormation:
    def __init__(self, ctx):
        p = ctx.params
        self.n = math.sqrt(MU_EARTH_M3PS2 / (R_EARTH_M + p["orbit_alt_m"]) ** 3)
        self.noise_std_m = p["position_noise_std_m"]
        self.r = np.array([a["r0_m"] for a in ctx.agents], dtype=float)
        self.v = np.array([a["v0_mps"] for a in ctx.agents], dtype=float)
        self.u = np.zeros_like(self.r)
        self.dv_total_mps = 0.0

    def columns(self):
        cols = []
        for i in range(1, len(self.r) + 1):
            for q, unit in (("r", "m"), ("v", "mps"), ("u", "mps2")):
                cols += [f"a{i}_{q}_{ax}_lvlh_{unit}" for ax in "xyz"]
        return cols + ["spread_m"]

    def readings(self, agent, rng):
        return self.r[agent - 1] + self.noise_std_m * rng.standard_normal(3)

    def apply_command(self, agent, u):
        self.u[agent - 1] = u

    def accel(self, r, v):
        n = self.n
        a = self.u.copy()
        a[:, 0] += 3.0 * n * n * r[:, 0] + 2.0 * n * v[:, 1]
        a[:, 1] += -2.0 * n * v[:, 0]
        a[:, 2] += -n * n * r[:, 2]
        return a

    def advance(self, dt_s):
        r, v = self.r, self.v
        k1r, k1v = v, self.accel(r, v)
        k2r, k2v = v + 0.5 * dt_s * k1v, self.accel(r + 0.5 * dt_s * k1r, v + 0.5 * dt_s * k1v)
        k3r, k3v = v + 0.5 * dt_s * k2v, self.accel(r + 0.5 * dt_s * k2r, v + 0.5 * dt_s * k2v)
        k4r, k4v = v + dt_s * k3v, self.accel(r + dt_s * k3r, v + dt_s * k3v)
        self.r = r + dt_s / 6.0 * (k1r + 2.0 * k2r + 2.0 * k3r + k4r)
        self.v = v + dt_s / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        self.dv_total_mps += float(np.sum(np.sqrt(np.sum(self.u * self.u, axis=1)))) * dt_s

    def row(self):
        spread = float(np.max(np.sqrt(np.sum((self.r - self.r.mean(axis=0)) ** 2, axis=1))))
        return np.concatenate([np.hstack([self.r, self.v, self.u]).ravel(), [spread]])

    def metrics(self):
        return {"dv_total_mps": self.dv_total_mps}
