"""The loop's parts are picked by name from registries; an unknown name fails with one clear line."""

from __future__ import annotations

import pytest

from closed_loop import (
    ESTIMATORS,
    OBSERVERS,
    REGISTRARS,
    GeometricObserver,
    KabschRegistrar,
    MLRegistrar,
    RenderedObserver,
    RobustKabschRegistrar,
    UnknownPartError,
)
from filters import MEKF, AttitudeEKF


def test_registries_map_the_config_names_to_the_parts():
    assert dict(OBSERVERS) == {"rendered": RenderedObserver, "geometric": GeometricObserver}
    assert dict(REGISTRARS) == {"kabsch": KabschRegistrar, "ransac": RobustKabschRegistrar, "ml": MLRegistrar}
    assert dict(ESTIMATORS) == {"ekf": AttitudeEKF, "mekf": MEKF}


@pytest.mark.parametrize(("registry", "part"), [(OBSERVERS, "observer"), (REGISTRARS, "registrar"),
                                                (ESTIMATORS, "estimator")])
def test_unknown_name_raises_one_line_naming_the_known_ones(registry, part):
    with pytest.raises(UnknownPartError) as err:
        registry["icp"]
    msg = str(err.value)
    assert "\n" not in msg
    assert msg == f"unknown {part} 'icp'; known: {', '.join(sorted(registry))}"
    assert isinstance(err.value, KeyError)


def test_membership_and_get_follow_the_mapping_protocol():
    assert "ml" in REGISTRARS and "icp" not in REGISTRARS
    assert REGISTRARS.get("icp") is None
    assert len(ESTIMATORS) == 2
