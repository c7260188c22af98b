"""reconstruction package (see ARCHITECTURE §1)."""
