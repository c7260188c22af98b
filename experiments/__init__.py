"""Experiments: the layer that turns configs into datasets, figures and commands (the ``coobs`` CLI)."""
