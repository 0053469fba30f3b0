"""Power of a paired t-test (raspv_experiments/power.py) against G*Power's published values, and
the n it asks for."""
from __future__ import annotations

import pytest

from raspv_experiments.power import effect_size_dz, paired_t_power, subjects_for_power


def test_power_matches_gpower():
    # G*Power 3.1, t tests, means: difference from constant (matched pairs), two tails, alpha 0.05
    assert paired_t_power(0.5, 34) == pytest.approx(0.8078, abs=5e-4)
    assert paired_t_power(0.8, 15) == pytest.approx(0.8213, abs=5e-4)
    assert paired_t_power(-0.5, 34) == paired_t_power(0.5, 34)                # two-sided
    assert paired_t_power(0.0, 20) == pytest.approx(0.05, abs=1e-9)          # no effect: alpha
    assert subjects_for_power(0.5, 0.8) == 34 and subjects_for_power(0.8, 0.8) == 15
    assert paired_t_power(1.06, 12) > 0.9 > paired_t_power(1.06, 9)
    assert subjects_for_power(0.5, 0.8, alpha=0.01) > 34


def test_effect_size_and_refusals():
    assert effect_size_dz([1.0, 2.0, 3.0]) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="at least 2 pairs"):
        paired_t_power(0.5, 1)
    with pytest.raises(ValueError, match="size 0"):
        subjects_for_power(0.0)
    with pytest.raises(ValueError, match="not all equal"):
        effect_size_dz([1.0, 1.0])
