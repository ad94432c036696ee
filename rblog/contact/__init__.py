"""rblog.contact."""
