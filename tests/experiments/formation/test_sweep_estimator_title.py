"""Closed-loop convergence maps name the estimator that ran, from the stored config and overrides."""

from __future__ import annotations

import json

import pytest
import xarray as xr

from experiments.scenarios.formation.figures import _sweep_estimator

CONFIG = 'kind = "formation"\n[estimator]\nregistration = "kabsch"\nfilter = "ekf"\n'


@pytest.mark.parametrize(("overrides", "swept", "expected"), [
    ({}, [], "EKF"),
    ({"estimator.filter": "smoother", "estimator.registration": "map"}, [], "smoother"),
    ({"estimator.filter": "mekf"}, [], "MEKF"),
    ({}, ["formation.distance_m", "estimator.filter"], "estimator"),
])
def test_the_title_names_the_filter_of_the_config_after_its_overrides(overrides, swept, expected):
    """A ``--set estimator.filter=smoother`` sweep of an EKF config is titled by the smoother, a swept filter by neither."""
    ds = xr.Dataset(attrs={"config_toml": CONFIG, "overrides": json.dumps(overrides), "swept_keys": json.dumps(swept)})
    assert _sweep_estimator(ds) == expected
