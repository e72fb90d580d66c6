"""One module per ``beambench`` subcommand: ``HELP``, ``add_arguments``, ``run``."""
