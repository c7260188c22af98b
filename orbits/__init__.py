"""orbits package (see ARCHITECTURE §1)."""
