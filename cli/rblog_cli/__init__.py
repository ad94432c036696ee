"""rblog's click front end (installed as the package ``rblog_cli``)."""
