"""vision package (see ARCHITECTURE §1)."""
