"""drivenav.viz."""
