"""The notebook-style script of docs/architecture.md builds the closed loop from parts and runs it.

The test reads the script from the page itself, so the documentation cannot drift from the code.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

PAGE = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def _script() -> str:
    text = PAGE.read_text()
    section = text.split("## Building the closed loop from Python", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, flags=re.S)
    assert match, "docs/architecture.md: no python block under 'Building the closed loop from Python'"
    return match.group(1)


def test_architecture_script_runs_twenty_epochs_and_tracks_the_target(capsys):
    namespace: dict = {}
    exec(compile(_script(), str(PAGE), "exec"), namespace)  # noqa: S102 - the page's own example
    printed = capsys.readouterr().out
    assert "increments used: 19 of 19" in printed
    result = namespace["result"]
    assert result.q_NT_est.shape == (20, 4)
    # Measured on seed 0: attitude error <= 0.70 deg, rate error <= 0.19 deg/s (the start), median
    # increment error 0.2 deg; bounds with margin.
    assert np.nanmax(namespace["attitude_error_deg"]) < 1.5
    assert namespace["rate_error_deg_s"][-1] < 0.15
    assert np.nanmedian(result.increment_error_deg) < 0.4
