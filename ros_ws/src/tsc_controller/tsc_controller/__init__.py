"""tsc_controller."""
