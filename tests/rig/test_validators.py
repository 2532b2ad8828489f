"""The one set of validators (rig.validation): a bad value gets one line naming the key, the value as
given and what is valid, in the caller's error class; a good value comes back as a plain number."""

import math

import numpy as np
import pytest

from processing.errors import SettingsError
from rig.validation import finite_at_least, integer, number, positive
from rig.errors import ConfigError


@pytest.mark.parametrize("value, kwargs, message", [
    (0.0, dict(lo=0.0, lo_open=True), "x = 0.0 is invalid: expected a finite number > 0"),
    (-1, dict(lo=0.0), "x = -1 is invalid: expected a finite number >= 0"),
    (600.0, dict(lo=0.0, lo_open=True, hi=500.0, unit="Hz"),
     "x = 600.0 is invalid: expected a finite number > 0 and <= 500 Hz"),
    (math.nan, {}, "x = nan is invalid: expected a finite number"),
    (math.inf, {}, "x = inf is invalid: expected a finite number"),
    (True, {}, "x = True is invalid: expected a finite number"),
    ("1.0", {}, "x = '1.0' is invalid: expected a finite number"),
    (np.float64(-2.5), dict(lo=0.0), "x = -2.5 is invalid: expected a finite number >= 0"),
    (2.0, dict(hi=1.0, valid="0 <= x <= 1"), "x = 2.0 is invalid: expected 0 <= x <= 1"),
])
def test_a_bad_number_is_named_with_its_value_and_what_is_valid(value, kwargs, message):
    with pytest.raises(ConfigError) as exc:
        number("x", value, **kwargs)
    assert str(exc.value) == message


def test_a_good_number_comes_back_as_a_float_and_inf_only_when_allowed():
    assert number("x", np.int64(3), lo=0.0) == 3.0 and type(number("x", np.int64(3))) is float
    assert positive("q", math.inf, allow_inf=True) == math.inf
    with pytest.raises(ConfigError, match=r"q = nan is invalid: expected a number > 0"):
        positive("q", math.nan, allow_inf=True)
    with pytest.raises(ConfigError, match=r"q = 0\.0 is invalid: expected > 0 \(inf for"):
        positive("q", 0.0, allow_inf=True, valid="> 0 (inf for no damping)")


def test_integers_reject_floats_and_bools_and_keep_the_callers_error_class():
    assert integer("n", np.int32(4), minimum=2) == 4
    for bad in (64.0, True, 1):
        with pytest.raises(SettingsError, match=rf"n = {bad!r} is invalid: expected an integer "
                                                r">= 2"):
            integer("n", bad, minimum=2, error=SettingsError)
    with pytest.raises(ValueError):  # SettingsError and ConfigError are both ValueErrors
        positive("fs", -1.0, error=SettingsError)


def test_finite_at_least_names_the_unit_of_its_bound():
    with pytest.raises(ConfigError) as exc:
        finite_at_least("psd.distance_m", 0.0, lo=0.0, strict=True, unit="m")
    assert str(exc.value) == "psd.distance_m = 0.0 is invalid: expected a finite number > 0 m"
    assert finite_at_least("k", 0, lo=0.0, strict=False, unit="") == 0.0
