"""drivenav.inspection."""
