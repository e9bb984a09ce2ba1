"""The bench's compute-bound Python agent: about 1 ms of work per step, then a zero command.
`work = "numpy"`: element-wise numpy on a 6-vector (numpy lets go of the GIL inside some of
these calls, so threads of one interpreter overlap a little); `work = "python"`: the same
arithmetic on plain floats (the GIL held throughout: in one interpreter the agents take turns). Written into the bench's
scratch directory by `orchestrator bench`; not a scenario users open."""
import math

import numpy as np


class Busy:
    def __init__(self, ctx):
        self.iterations = ctx.params["iterations"]
        self.numpy = ctx.params["work"] == "numpy"
        self.x = np.ones(6)

    def columns(self):
        return ["x0_1"]

    def share(self, k, t_s, y):
        x = self.x
        if self.numpy:
            for _ in range(self.iterations):
                x = np.sin(x) * 0.5 + 0.5
        else:
            v = [float(e) for e in x]
            for _ in range(self.iterations):
                v = [math.sin(e) * 0.5 + 0.5 for e in v]
            x = np.array(v)
        self.x = x
        return [0.0, 0.0, 0.0], x

    def step(self, dt_s, neighbours):
        pass

    def row(self):
        return [self.x[0]]

    def save_state(self):
        return self.x.tobytes()

    def restore_state(self, state):
        self.x = np.frombuffer(state).copy()
