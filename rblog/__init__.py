"""rblog: simulate rigid bodies, record what happened, and audit the recording."""

__version__ = "0.1.0"
