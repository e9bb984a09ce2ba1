"""Fixtures of tests/system/python.rs: one class per mistake a user makes, each otherwise a
working two-agent algorithm for the double-integrator plant (3 readings, 3 command components,
3 share values)."""
import math
import time


class Fine:
    def __init__(self, ctx):
        self.id = ctx.id
        self.y = [0.0, 0.0, 0.0]

    def columns(self):
        return ["y_x_m"]

    def share(self, k, t_s, y):
        self.y = [float(v) for v in y]
        return [0.0, 0.0, 0.0], self.y

    def step(self, dt_s, neighbours):
        pass

    def row(self):
        return [self.y[0]]

    def save_state(self):
        return b""

    def restore_state(self, state):
        pass


class MissingStep:
    def __init__(self, ctx):
        pass

    def columns(self):
        return []

    def share(self, k, t_s, y):
        return [0.0] * 3, [0.0] * 3

    def row(self):
        return []

    def save_state(self):
        return b""

    def restore_state(self, state):
        pass


class WrongSignature(Fine):
    def share(self, k):
        return [0.0] * 3, [0.0] * 3


class RaisesInStep(Fine):
    def step(self, dt_s, neighbours):
        if self.y[0] > -1e9:  # always, once the first share came
            raise ValueError(f"agent {self.id}: gain matrix not positive definite")


class WrongLength(Fine):
    def share(self, k, t_s, y):
        return [0.0, 0.0], [0.0] * 3


class NotFinite(Fine):
    def share(self, k, t_s, y):
        return [0.0, math.nan if k >= 5 else 0.0, 0.0], [0.0] * 3


class WrongType(Fine):
    def share(self, k, t_s, y):
        return "thrust", [0.0] * 3


class NeverReturns(Fine):
    def step(self, dt_s, neighbours):
        if self.id == 2:
            while True:
                time.sleep(0.05)
