"""drivenav.semantics."""
