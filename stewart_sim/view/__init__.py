"""Views of runs in the browser: the live view of the emulated device (live)."""
