"""Private helpers: files and caches, input validation, progress bars, interpolation."""
