"""filters package (see ARCHITECTURE §1)."""
