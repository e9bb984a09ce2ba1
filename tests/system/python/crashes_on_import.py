"""A module whose import fails (fixture of tests/system/python.rs)."""
GAINS = {"kp": 1.0}
KD = GAINS["kd"]


class Controller:
    pass
