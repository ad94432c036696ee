"""rblog.record."""
