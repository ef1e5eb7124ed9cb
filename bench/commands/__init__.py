"""One module per `proxops` sub-command."""
