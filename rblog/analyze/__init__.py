"""rblog.analyze."""
