"""drivenav.eval."""
