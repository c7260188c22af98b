"""formation package (see ARCHITECTURE §1)."""
