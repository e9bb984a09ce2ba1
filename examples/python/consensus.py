"""Consensus formation keeping, in Python: the `consensus-formation` kind of Cohort re-written
operation for operation, so that its telemetry equals the Rust kind's bit for bit.

Each agent estimates its own position and velocity from noisy position readings with a
Luenberger observer, publishes the estimate, and steers toward its slot on a regular polygon
relative to the positions its neighbours publish:

    u_i = -kp * sum_j [(r_i - r_j) - (p_i - p_j)] - kd * v_i
    dr_i/dt = v_i + l1 (y_i - r_i),   dv_i/dt = u_i + l2 (y_i - r_i)   (RK4, y and u held)

Plain Python floats, every sum in the Rust order: IEEE doubles give the same bits.
"""
import math
import pickle


def slot_m(radius_m, i, n):
    a = math.tau * float(i - 1) / float(n)
    return [radius_m * math.cos(a), radius_m * math.sin(a), 0.0]


def axpy(x, a, d):
    return [x[0] + a * d[0], x[1] + a * d[1], x[2] + a * d[2]]


class ConsensusFormation:
    def __init__(self, ctx):
        p = ctx.params
        self.radius_m = p["formation_radius_m"]
        self.kp = p["kp_per_s2"]
        self.kd = p["kd_per_s"]
        self.l1 = p["observer_l1_per_s"]
        self.l2 = p["observer_l2_per_s2"]
        self.slot = slot_m(self.radius_m, ctx.id, ctx.n_agents)
        # neighbour id -> [its slot, its latest published position estimate or None]
        self.nb = {j: [slot_m(self.radius_m, j, ctx.n_agents), None] for j in ctx.neighbours}
        self.order = list(ctx.neighbours)
        self.r = [0.0, 0.0, 0.0]
        self.v = [0.0, 0.0, 0.0]
        self.y = [0.0, 0.0, 0.0]
        self.u = [0.0, 0.0, 0.0]
        self.initialised = False

    def columns(self):
        return [f"{q}_{ax}_{unit}" for q, unit in (("r_hat", "m"), ("v_hat", "mps"), ("u", "mps2"))
                for ax in "xyz"]

    def command(self):
        u = [0.0, 0.0, 0.0]
        for j in self.order:
            slot_j, r_j = self.nb[j]
            if r_j is not None:
                for a in range(3):
                    u[a] -= self.kp * ((self.r[a] - r_j[a]) - (self.slot[a] - slot_j[a]))
        for a in range(3):
            u[a] -= self.kd * self.v[a]
        return u

    def share(self, k, t_s, y):
        self.y = [float(y[0]), float(y[1]), float(y[2])]
        if not self.initialised:
            self.r = list(self.y)  # start the observer on the first reading
            self.initialised = True
        self.u = self.command()
        return self.u, self.r + self.v

    def deriv(self, r, v):
        dr = [0.0, 0.0, 0.0]
        dv = [0.0, 0.0, 0.0]
        for a in range(3):
            res = self.y[a] - r[a]
            dr[a] = v[a] + self.l1 * res
            dv[a] = self.u[a] + self.l2 * res
        return dr, dv

    def step(self, dt_s, neighbours):
        r, v = self.r, self.v
        k1r, k1v = self.deriv(r, v)
        k2r, k2v = self.deriv(axpy(r, dt_s / 2.0, k1r), axpy(v, dt_s / 2.0, k1v))
        k3r, k3v = self.deriv(axpy(r, dt_s / 2.0, k2r), axpy(v, dt_s / 2.0, k2v))
        k4r, k4v = self.deriv(axpy(r, dt_s, k3r), axpy(v, dt_s, k3v))
        self.r = [r[a] + dt_s / 6.0 * (k1r[a] + 2.0 * k2r[a] + 2.0 * k3r[a] + k4r[a]) for a in range(3)]
        self.v = [v[a] + dt_s / 6.0 * (k1v[a] + 2.0 * k2v[a] + 2.0 * k3v[a] + k4v[a]) for a in range(3)]
        for j, values in neighbours.items():
            if j in self.nb and len(values) >= 3:
                self.nb[j][1] = [float(values[0]), float(values[1]), float(values[2])]

    def row(self):
        return self.r + self.v + self.u

    def save_state(self):
        return pickle.dumps((self.r, self.v, self.y, self.u, self.initialised, self.nb))

    def restore_state(self, state):
        self.r, self.v, self.y, self.u, self.initialised, self.nb = pickle.loads(state)
