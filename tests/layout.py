"""The stream of a one-curve job in the column layout of the tests written before paths.

A `curve:` job is a path of one block: its column n is 0 on every tick, and its u is the
curve's own parameter.  Tests of single-curve behaviour index k, t, u, axes, v, a.
"""
import numpy as np


def one_curve(data: np.ndarray) -> np.ndarray:
    """*data* (k, n, t, u, axes, v, a) without its n column, after checking that n is 0 throughout."""
    assert (data[:, 1] == 0).all(), "a one-curve job's stream has n = 0 on every tick"
    return np.delete(data, 1, axis=1)
