"""File writing helpers: atomic writes that never replace a device, and locks."""
