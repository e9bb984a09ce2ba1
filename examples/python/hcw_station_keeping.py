"""Station keeping about a target spacecraft in Hill's frame: a Kalman filter on the
Clohessy-Wiltshire (HCW) relative motion and a PD controller with the HCW terms cancelled.

Flown on Cohort's `orbital` plant (ECI truth with J2 and drag; readings in the LVLH frame of a
reference point on the target's orbit: x radial, y in-track, z orbit normal). With an identity
output matrix, the first three readings are y = q0 - qi (target relative to this servicer), the
next three per neighbour d_ij = qj - qi.

State x = [e, de/dt], e = qi - q0 (this servicer relative to the target). HCW, mean motion n:
    e_x'' = 3 n^2 e_x + 2 n e_y' + u_x,   e_y'' = -2 n e_x' + u_y,   e_z'' = -n^2 e_z + u_z
Control: u = -a_hcw(e, e') - kp (e - slot) - kd e', clipped to u_max per axis.
Discrete model: Phi = exp(A dt) by a 6th-order Taylor series, B_d = (sum A^k dt^(k+1)/(k+1)!) B.
"""
import math
import pickle

import numpy as np

MU_EARTH_M3PS2 = 3.986004418e14
R_EARTH_M = 6378137.0


def hcw_matrices(n, dt):
    a = np.zeros((6, 6))
    a[0:3, 3:6] = np.eye(3)
    a[3, 0] = 3.0 * n * n
    a[3, 4] = 2.0 * n
    a[4, 3] = -2.0 * n
    a[5, 2] = -n * n
    b = np.zeros((6, 3))
    b[3:6, :] = np.eye(3)
    phi = np.eye(6)
    gamma = np.eye(6) * dt
    term = np.eye(6)
    for k in range(1, 7):
        term = term @ a * (dt / k)
        phi = phi + term
        gamma = gamma + term * (dt / (k + 1))
    return a, phi, gamma @ b


class HcwStationKeeping:
    def __init__(self, ctx):
        p = ctx.params
        self.slot = np.array(p["slot_m"], dtype=float)
        self.n = math.sqrt(MU_EARTH_M3PS2 / (R_EARTH_M + p["orbit_alt_m"]) ** 3)
        wn, zeta = p["bandwidth_radps"], p["damping"]
        self.kp, self.kd = wn * wn, 2.0 * zeta * wn
        self.u_max = p["u_max_mps2"]
        self.sigma = p["noise_std_m"]
        self.q_accel = p["process_noise_mps2"]
        _, self.phi, self.bd = hcw_matrices(self.n, ctx.dt_s)
        self.qd = (self.q_accel ** 2) * (self.bd @ self.bd.T)
        self.h = np.hstack([np.eye(3), np.zeros((3, 3))])
        self.r = np.eye(3) * self.sigma ** 2
        self.n_nb = len(ctx.neighbours)
        self.x = np.zeros(6)
        self.p = np.diag([self.sigma ** 2] * 3 + [1.0] * 3)
        self.u = np.zeros(3)
        self.nearest_m = math.inf
        self.started = False

    def columns(self):
        names = [f"e_hat_{a}_lvlh_m" for a in "xyz"] + [f"v_hat_{a}_lvlh_mps" for a in "xyz"]
        names += [f"u_{a}_lvlh_mps2" for a in "xyz"]
        return names + ["slot_error_m", "nearest_neighbour_m"]

    def share(self, k, t_s, y):
        z = -np.asarray(y[0:3])
        if not self.started:
            self.x[0:3] = z
            self.started = True
        else:  # measurement update (the prediction ran in step())
            s = self.h @ self.p @ self.h.T + self.r
            gain = self.p @ self.h.T @ np.linalg.inv(s)
            self.x = self.x + gain @ (z - self.h @ self.x)
            self.p = (np.eye(6) - gain @ self.h) @ self.p
        e, v = self.x[0:3], self.x[3:6]
        n = self.n
        a_hcw = np.array([3.0 * n * n * e[0] + 2.0 * n * v[1], -2.0 * n * v[0], -n * n * e[2]])
        self.u = np.clip(-a_hcw - self.kp * (e - self.slot) - self.kd * v, -self.u_max, self.u_max)
        d = np.asarray(y[3:3 + 3 * self.n_nb]).reshape(self.n_nb, 3)
        self.nearest_m = float(np.min(np.sqrt(np.sum(d * d, axis=1)))) if self.n_nb else math.inf
        return self.u, self.x

    def step(self, dt_s, neighbours):
        # Time update with the command held over the step.
        self.x = self.phi @ self.x + self.bd @ self.u
        self.p = self.phi @ self.p @ self.phi.T + self.qd

    def row(self):
        err = float(np.linalg.norm(self.x[0:3] - self.slot))
        nearest = self.nearest_m if math.isfinite(self.nearest_m) else -1.0
        return np.concatenate([self.x, self.u, [err, nearest]])

    def save_state(self):
        return pickle.dumps((self.x, self.p, self.u, self.nearest_m, self.started))

    def restore_state(self, state):
        self.x, self.p, self.u, self.nearest_m, self.started = pickle.loads(state)
