"""drivenav.agent."""
