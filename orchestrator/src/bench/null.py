"""The bench's null Python agent: what crossing into Python costs, with nothing to compute (the
Python twin of the `null` algorithm kind). Written into the bench's scratch directory."""


class Null:
    def __init__(self, ctx):
        self.command = [0.0] * len(ctx.command)
        self.values = [0.0] * ctx.share_values

    def columns(self):
        return []

    def share(self, k, t_s, y):
        return self.command, self.values

    def step(self, dt_s, neighbours):
        pass

    def row(self):
        return []

    def save_state(self):
        return b""

    def restore_state(self, state):
        pass
