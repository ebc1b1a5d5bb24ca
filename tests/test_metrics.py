"""The fit metrics: a free run that ran away scores infinitely badly instead of raising or warning."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.errors import ConfigError
from servoid.ident.metrics import free_run_nrmse, nrmse


def test_a_free_run_that_ran_away_fits_infinitely_badly_and_a_sound_one_as_nrmse_says() -> None:
    y = np.sin(np.arange(200) / 7.0)
    near = y + 0.01 * np.cos(np.arange(200) / 3.0)
    assert free_run_nrmse(y, near) == nrmse(y, near)
    # past what a square holds (the live Feetech twin's candidate reached 6e255): a RuntimeWarning in nrmse
    runaway = y * 10.0 ** np.linspace(0.0, 255.0, y.size)
    assert free_run_nrmse(y, runaway) == math.inf
    assert free_run_nrmse(y, np.where(np.arange(200) > 150, np.nan, y)) == math.inf
    with pytest.raises(ConfigError, match="not finite"):
        nrmse(y, np.where(np.arange(200) > 150, np.inf, y))  # the plain metric still refuses it
