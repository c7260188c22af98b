"""chaser package (see ARCHITECTURE §1)."""
