"""Small numerical helpers shared by the tests."""

import numpy as np


def fitted_slope(x, y):
    """Least-squares slope of log|y| against log x."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.abs(np.asarray(y, float))), 1)[0])
